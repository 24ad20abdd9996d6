// taskflow view: the page of one run, live or replayed, drawn from its record (taskflow/operate/view.py serves it).
// Plain JavaScript, no library, no network beyond the page's own server; common.js is loaded first.
"use strict";

const S = {
  machine: null, nodes: {}, els: {}, cols: [], col: {}, rows: [], rowNext: 0, recs: [], recNext: 0,
  cursor: 0, follow: true, live: false, running: true, plots: [], playing: null, ops: null, cpOf: new Map(),
  frames: [], frameNext: 0, cams: {},
};
const within = (path, p) => p === "" || path === p || path.startsWith(p + ".");
const leavesOf = (row) => (row ? row[1].split("|").filter(Boolean) : []);
const fmt = (x) => (x === null || x === undefined || Number.isNaN(x) ? "–" : Math.abs(x) >= 1e4 || (Math.abs(x) < 1e-3 && x !== 0) ? x.toExponential(3) : (+x.toPrecision(4)).toString());


// the routes are asked for relative to the page's address: the page of a campaign's kept trial is served
// under the campaign's (…/run/trial-00003/, taskflow/operate/campaign_http.py), a run's at the root
const IN_CAMPAIGN = window.location.pathname.startsWith("/run/");

async function getJSON(url) {
  const r = await fetch(url, { cache: "no-store", headers: authHeaders() });
  if (!r.ok) throw new Error(`${url}: HTTP ${r.status}`);
  return r.json();
}

// -- the machine ------------------------------------------------------------------------------------------
function index(node, parent) {
  node.parent = parent;
  S.nodes[node.path] = node;
  node.children.forEach((c) => index(c, node));
}

function buildChart(node, into, initial) {
  const el = document.createElement("div");
  el.className = `st ${node.kind}` + (initial ? " initial" : "") + (node.path === "" ? " root" : "");
  el.dataset.path = node.path;
  const tags = [node.task, node.action && `action ${node.action}`, node.loop, node.history && "history",
    node.outcome && `final: ${node.outcome}`, node.kind === "parallel" && "parallel"].filter(Boolean);
  const nm = document.createElement("div");
  nm.className = "nm";
  nm.textContent = node.name;
  nm.title = [node.path || node.name, node.description, ...node.transitions.map((t) => `→ ${t.target}: ${t.label}`)]
    .filter(Boolean).join("\n");
  if (tags.length) {
    const t = document.createElement("span");
    t.className = "tag";
    t.textContent = tags.join(" · ");
    nm.appendChild(t);
  }
  el.appendChild(nm);
  if (node.children.length) {
    const kids = document.createElement("div");
    kids.className = "kids";
    node.children.forEach((c) => buildChart(c, kids, node.kind !== "parallel" && c.name === node.initial));
    el.appendChild(kids);
  }
  S.els[node.path] = el;
  into.appendChild(el);
}

function guardMetrics(tree, out) {
  if (tree.metric) out.push(tree.metric);
  else tree.args.forEach((a) => guardMetrics(a, out));
  return out;
}

function allTransitions() {
  return Object.values(S.nodes).flatMap((n) => n.transitions);
}

// -- evaluation against a trace row ------------------------------------------------------------------------
function metricAt(row, name) {
  const j = S.col["m." + name];
  return j === undefined || !row ? null : row[j];
}

const CMP = { "<": (a, b) => a < b, "<=": (a, b) => a <= b, ">": (a, b) => a > b, ">=": (a, b) => a >= b,
  "==": (a, b) => a === b, "!=": (a, b) => a !== b };

function evalGuard(tree, row) {
  if (tree.metric) {
    let x = metricAt(row, tree.metric);
    if (x === null || tree.value === null) return false;
    if (tree.abs) x = Math.abs(x);
    return CMP[tree.cmp](x, tree.value);
  }
  if (tree.op === "not") return !evalGuard(tree.args[0], row);
  if (tree.op === "and") return tree.args.every((a) => evalGuard(a, row));
  return tree.args.some((a) => evalGuard(a, row));
}

function comparisons(tree, out) {
  if (tree.metric) out.push(tree);
  else tree.args.forEach((a) => comparisons(a, out));
  return out;
}

// when the state at ``path`` was last entered, as of row i (from the transition records; else the first row)
function enteredAt(path, i, first) {
  const t = S.rows[i][0];
  let best = null;
  for (const r of S.recs) {
    if (!r.to) continue;  // an operator action or a property's violation: no change of state
    if (r.t >= t) break;
    const fromOut = r.from === "__start__" || !within(r.from, path) || (r.from === r.to && r.to === path);
    if (within(r.to, path) && fromOut) {
      best = r.t;
      if (first) break;
    }
  }
  if (best !== null) return best;
  let j = i;
  while (j > 0 && leavesOf(S.rows[j - 1]).some((l) => within(l, path))) j--;
  return S.rows[j][0];
}

// sim time the operator held the robot between ``since`` and row i: held ticks (event ``hold``) do not count
// toward ``after`` (the engine's operating clock, docs/missions.md "Operating a running mission")
function heldSince(since, i, dt) {
  let held = 0;
  for (let j = i - 1; j >= 0 && S.rows[j][0] >= since - 1e-9; j--) {
    if (S.rows[j][2] && S.rows[j][2].split("|").includes("hold")) held += dt;
  }
  return held;
}

// -- rendering ---------------------------------------------------------------------------------------------
function render() {
  if (!S.rows.length) return;
  const i = Math.min(S.cursor, S.rows.length - 1);
  const row = S.rows[i];
  const t = row[0];
  const leaves = leavesOf(row);
  $("cur-t").textContent = t.toFixed(3);
  $("cur-t").dataset.t = String(t);
  $("cur-state").textContent = row[1];
  $("cur-state").dataset.row = String(i);
  $("timeline").max = String(S.rows.length - 1);
  $("timeline").value = String(i);
  $("row-info").textContent = `tick ${i + 1} of ${S.rows.length}` + (row[2] ? `  events: ${row[2]}` : "");
  const tin = leaves.map((l) => `${l.split(".").pop()} ${(t - enteredAt(l, i, false)).toFixed(2)} s`).join(", ");
  $("time-in-state").textContent = tin ? `time in state: ${tin}` : "";
  renderChart(leaves);
  renderGuards(leaves, i);
  renderTransitions(t);
  renderProperties(t);
  renderPlots(i);
  renderPath(i);
  renderCameras(t, S.follow && S.live);
}

function renderChart(leaves) {
  const outcome = S.summary && S.summary.outcome;
  for (const [path, el] of Object.entries(S.els)) {
    const active = leaves.includes(path);
    el.classList.toggle("active", active);
    el.classList.toggle("on-path", !active && path !== "" && leaves.some((l) => within(l, path)));
    el.classList.toggle("failed", active && outcome === "failed");
    el.classList.toggle("aborted", active && outcome === "aborted");
  }
}

function outgoing(leaves) {
  const seen = new Set();
  const out = [];
  for (const leaf of leaves) {
    for (let n = S.nodes[leaf]; n && n.path !== ""; n = n.parent) {
      for (const tr of n.transitions) {
        if (!seen.has(tr.index)) {
          seen.add(tr.index);
          out.push(tr);
        }
      }
    }
  }
  return out;
}

function bar(frac) {
  const b = document.createElement("span");
  b.className = "bar";
  const f = document.createElement("i");
  f.style.width = `${Math.max(0, Math.min(1, frac)) * 100}%`;
  b.appendChild(f);
  return b;
}

function renderGuards(leaves, i) {
  const body = $("guards").tBodies[0];
  body.textContent = "";
  const row = S.rows[i];
  const t = row[0];
  const dt = 1 / S.machine.rate_hz;
  const events = row[2] ? row[2].split("|") : [];
  for (const tr of outgoing(leaves)) {
    const r = document.createElement("tr");
    r.dataset.index = String(tr.index);
    cell(r, tr.source);
    cell(r, `→ ${tr.target}: ${tr.label}`);
    cell(r, tr.kind);
    const cond = cell(r, "");
    const prog = cell(r, "");
    if (tr.guard) {
      for (const c of comparisons(tr.guard.tree, [])) {
        const x = metricAt(row, c.metric);
        const ok = x !== null && c.value !== null && CMP[c.cmp](c.abs ? Math.abs(x) : x, c.value);
        const span = document.createElement("div");
        span.className = `cmp ${ok}`;
        const unit = S.machine.metric_units[c.metric] || "";
        const v = document.createElement("span");
        v.className = "val";
        v.dataset.metric = c.metric;
        v.dataset.value = x === null ? "" : String(x);
        v.textContent = fmt(x);
        span.append(`${c.abs ? `|${c.metric}|` : c.metric} = `, v,
          ` ${unit} ${c.cmp} ${c.value === null ? "$" + c.param : fmt(c.value)} ${unit}`.replace(/ {2,}/g, " "));
        cond.appendChild(span);
      }
    }
    const holds = tr.guard ? evalGuard(tr.guard.tree, row) : null;
    if (tr.kind === "guard") {
      if (tr.dwell > 0) {
        let j = i;
        while (j >= 0 && evalGuard(tr.guard.tree, S.rows[j]) && t - S.rows[j][0] < tr.dwell + dt) j--;
        const held = holds ? t - S.rows[j + 1][0] : 0;
        prog.append(bar(held / tr.dwell), ` held ${held.toFixed(2)} / ${tr.dwell} s`);
      } else {
        prog.textContent = holds ? "holds: fires this tick" : "fires when it holds";
      }
      cond.className = holds ? "ok" : "no";
    } else if (tr.kind === "timeout") {
      const since = enteredAt(tr.since, i, tr.since_first);
      const held = heldSince(since, i, dt);
      const left = tr.after - (t - since - held);
      prog.append(bar((t - since - held) / tr.after), ` ${Math.max(0, left).toFixed(2)} s left of ${tr.after} s` +
        (held > 0 ? ` (${held.toFixed(2)} s held, not counted)` : ""));
      cond.textContent = `after ${tr.after} s since ${tr.since}${tr.since_first ? " (first entered)" : ""}`;
    } else if (tr.kind === "event") {
      const seen = events.includes(tr.event);
      cond.prepend(`on ${tr.event}${tr.guard ? " when:" : ""}`);
      prog.textContent = seen ? "event this tick" : "waiting for the event";
      cond.className = seen ? "ok" : "";
    } else {
      cond.textContent = `when ${tr.source} finishes${tr.outcome ? " with " + tr.outcome : ""}`;
    }
    body.appendChild(r);
  }
}

function recordText(r) {
  if (r.cause === "property") {
    const atoms = Object.entries(r.atoms || {}).map(([k, v]) => `${k}=${typeof v === "number" ? fmt(v) : v}`).join(", ");
    return `${r.t.toFixed(2)} s  property ${r.property} violated (${r.pattern}, in ${r.state})${atoms ? " [" + atoms + "]" : ""}`;
  }
  if (r.cause === "operator" && r.action) {
    const args = Object.entries(r.args || {}).map(([k, v]) => `${k}=${v}`).join(" ");
    return `${r.t.toFixed(2)} s  operator ${r.action}${args ? " " + args : ""} by ${r.who} (in ${r.state})`;
  }
  const why = r.cause === "guard" ? `guard ${r.label}` + (r.metrics ? " [" + Object.entries(r.metrics).map(([k, v]) => `${k}=${fmt(v)}`).join(", ") + "]" : "")
    : r.cause === "event" ? `event ${r.event}` + (r.metrics ? " [" + Object.entries(r.metrics).map(([k, v]) => `${k}=${fmt(v)}`).join(", ") + "]" : "")
    : r.cause === "timeout" ? `timeout ${r.label}`
    : r.cause === "done" ? `done (${r.outcome})`
    : r.cause === "next_item" ? `next item ${r.item} (after ${r.outcome})`
    : r.cause === "retry" ? `retry item ${r.item}, attempt ${r.attempt} (after ${r.outcome})`
    : r.cause === "operator" ? `pre-empted by ${r.who}` : r.cause;
  return `${r.t.toFixed(2)} s  ${r.from} → ${r.to}  ${why}${r.resumed ? " (history)" : ""}`;
}

// each declared property's verdict as of the cursor's time: violated once its record's tick is past; at the end of
// a finished run, the summary's verdict (held, violated, not_decided)
function renderProperties(t) {
  const props = (S.machine && S.machine.properties) || [];
  const ul = $("properties");
  ul.hidden = $("properties-head").hidden = props.length === 0;
  ul.textContent = "";
  const ended = S.summary && S.summary.properties;
  const atEnd = !S.rows.length || S.cursor >= S.rows.length - 1;
  for (const p of props) {
    const rec = S.recs.find((r) => r.cause === "property" && r.property === p.name);
    let verdict = "holds so far";
    let cls = "";
    if (rec && rec.t <= t + 1e-9) {
      verdict = `violated at ${rec.t.toFixed(2)} s in ${rec.state}`;
      cls = "violated";
    } else if (ended && ended[p.name] && atEnd) {
      verdict = ended[p.name].verdict + (ended[p.name].t != null ? ` at ${(+ended[p.name].t).toFixed(2)} s` : "");
      cls = ended[p.name].verdict;
    }
    const li = document.createElement("li");
    li.dataset.property = p.name;
    li.dataset.verdict = cls || "open";
    li.className = cls;
    li.textContent = `${p.name} (${p.pattern}): ${verdict}`;
    li.title = (p.description ? p.description + " — " : "") + p.text;
    ul.appendChild(li);
  }
}

function renderTransitions(t) {
  const ol = $("transitions");
  ol.textContent = "";
  let current = null;
  for (let k = S.recs.length - 1; k >= 0; k--) {
    const r = S.recs[k];
    const li = document.createElement("li");
    li.textContent = recordText(r);
    li.dataset.t = String(r.t);
    li.title = "show the first tick after it";
    li.onclick = () => {
      stopFollowing();
      const k = S.rows.findIndex((row) => row[0] > r.t + 1e-9);
      seek(k < 0 ? S.rows.length - 1 : k);
    };
    const past = r.t < t || (r.t === t && r.cause === "operator");
    if (!past) li.classList.add("future");
    if (r.cause === "operator") li.classList.add("op");
    if (r.cause === "property") li.classList.add("prop");
    if (r.cause === "retry") li.classList.add("retry");
    if (past && current === null) current = li;
    ol.appendChild(li);
  }
  if (current) {
    current.classList.add("current");
    ol.scrollTop = current.offsetTop - ol.offsetTop - 40;  // the list scrolls, not the page
  }
}

// -- plots -------------------------------------------------------------------------------------------------
function thresholds(metric) {
  const out = [];
  for (const tr of allTransitions()) {
    if (!tr.guard) continue;
    for (const c of comparisons(tr.guard.tree, [])) {
      if (c.metric === metric && c.value !== null) {
        out.push({ v: c.value, label: `${c.cmp} ${fmt(c.value)} (${tr.source} → ${tr.target})` });
        if (c.abs) out.push({ v: -c.value, label: "" });
      }
    }
  }
  return out;
}

function addPlot(metric) {
  if (S.plots.some((p) => p.metric === metric) || S.col["m." + metric] === undefined) return;
  const div = document.createElement("div");
  div.className = "plot";
  const title = document.createElement("div");
  title.className = "title";
  const canvas = document.createElement("canvas");
  canvas.width = 520;
  canvas.height = 110;
  canvas.dataset.metric = metric;
  div.append(title, canvas);
  $("plots").appendChild(div);
  S.plots.push({ metric, canvas, title, th: thresholds(metric) });
}

function axes(ctx, w, h, pad) {
  ctx.clearRect(0, 0, w, h);
  ctx.strokeStyle = "#bbb";
  ctx.strokeRect(pad.l, pad.t, w - pad.l - pad.r, h - pad.t - pad.b);
}

function renderPlots(i) {
  const t0 = S.rows[0][0];
  const t1 = Math.max(S.rows[S.rows.length - 1][0], t0 + 1e-6);
  const tc = S.rows[i][0];
  for (const p of S.plots) {
    const j = S.col["m." + p.metric];
    const unit = S.machine.metric_units[p.metric];
    p.title.textContent = `${p.metric}${unit ? " [" + unit + "]" : ""} = ${fmt(S.rows[i][j])}  ` +
      (p.th.length ? "— dashed: guard thresholds" : "");
    const ctx = p.canvas.getContext("2d");
    const w = p.canvas.width, h = p.canvas.height, pad = { l: 46, r: 6, t: 6, b: 16 };
    axes(ctx, w, h, pad);
    let lo = Infinity, hi = -Infinity;
    for (const r of S.rows) if (r[j] !== null) { lo = Math.min(lo, r[j]); hi = Math.max(hi, r[j]); }
    for (const th of p.th) { lo = Math.min(lo, th.v); hi = Math.max(hi, th.v); }
    if (!Number.isFinite(lo)) { lo = 0; hi = 1; }
    if (hi - lo < 1e-12) { hi += 0.5; lo -= 0.5; }
    const X = (t) => pad.l + ((t - t0) / (t1 - t0)) * (w - pad.l - pad.r);
    const Y = (v) => h - pad.b - ((v - lo) / (hi - lo)) * (h - pad.t - pad.b);
    ctx.fillStyle = "#666";
    ctx.font = "10px sans-serif";
    ctx.fillText(fmt(hi), 2, pad.t + 8);
    ctx.fillText(fmt(lo), 2, h - pad.b);
    ctx.fillText(`${t0.toFixed(1)} s`, pad.l, h - 3);
    ctx.fillText(`${t1.toFixed(1)} s`, w - pad.r - 40, h - 3);
    ctx.strokeStyle = "#e0e0e0";
    for (const r of S.recs) if (r.to) { ctx.beginPath(); ctx.moveTo(X(r.t), pad.t); ctx.lineTo(X(r.t), h - pad.b); ctx.stroke(); }
    ctx.setLineDash([4, 3]);
    ctx.strokeStyle = "#e65100";
    for (const th of p.th) { ctx.beginPath(); ctx.moveTo(pad.l, Y(th.v)); ctx.lineTo(w - pad.r, Y(th.v)); ctx.stroke(); }
    ctx.setLineDash([]);
    ctx.strokeStyle = "#1565c0";
    ctx.beginPath();
    let pen = false;
    const stride = Math.max(1, Math.floor(S.rows.length / 2000));
    for (let k = 0; k < S.rows.length; k += stride) {
      const v = S.rows[k][j];
      if (v === null) { pen = false; continue; }
      if (pen) ctx.lineTo(X(S.rows[k][0]), Y(v)); else ctx.moveTo(X(S.rows[k][0]), Y(v));
      pen = true;
    }
    ctx.stroke();
    ctx.strokeStyle = "#c62828";
    ctx.beginPath(); ctx.moveTo(X(tc), pad.t); ctx.lineTo(X(tc), h - pad.b); ctx.stroke();
  }
}

// -- top view ----------------------------------------------------------------------------------------------
// What it draws is the mission's declared scene (taskflow/readers/scene.py, as the figures of taskflow/readers/plots.py):
// the markers the world and the tasks declare, and the path of the point each state's guards measure.
const ROLE_COLOUR = { goal: "crimson", waypoint: "crimson", keyframe: "darkorange", object: "black", start: "dimgray",
  obstacle: "seagreen", boundary: "black" };  // the figures' colours (taskflow/readers/plots.py, _ROLE_STYLE)

// the control point of a row's state: its leaf's, or the first of parallel leaves that declares one (Scene.control_point)
function controlPointOf(state) {
  if (!S.cpOf.has(state)) {
    const cps = S.machine.control_points || {};
    S.cpOf.set(state, state.split("|").map((leaf) => cps[leaf]).find(Boolean) || null);
  }
  return S.cpOf.get(state);
}

// the robot's reported pose at a row, [x, y, yaw] (yaw null when not recorded), or null
function poseAt(r) {
  const xy = S.machine.xy;
  const x = r[S.col[xy[0]]], y = r[S.col[xy[1]]];
  if (x === null || x === undefined || y === null || y === undefined) return null;
  const yaw = xy[2] && S.col[xy[2]] !== undefined ? r[S.col[xy[2]]] : null;
  return [x, y, yaw];
}

// the point drawn for a row: the control point of its state, d ahead of the pose (ControlPoint.of), else the pose
function controlAt(r) {
  const p = poseAt(r);
  if (!p) return null;
  const cp = controlPointOf(r[1]);
  if (!cp || p[2] === null) return [p[0], p[1]];
  const [a, b] = cp.offset, c = Math.cos(p[2]), s = Math.sin(p[2]);
  return [p[0] + a * c - b * s, p[1] + a * s + b * c];
}

function drawMarker(ctx, m, X, Y, s) {
  const colour = ROLE_COLOUR[m.kind] || "#555";
  ctx.strokeStyle = colour; ctx.fillStyle = colour; ctx.lineWidth = 1.5;
  const pts = m.points;
  if (m.closed || pts.length > 1) {
    ctx.beginPath();
    pts.forEach((p, k) => (k ? ctx.lineTo(X(p[0]), Y(p[1])) : ctx.moveTo(X(p[0]), Y(p[1]))));
    if (m.closed) ctx.closePath();
    if (m.closed && m.kind === "obstacle") { ctx.globalAlpha = 0.5; ctx.fill(); ctx.globalAlpha = 1; } else ctx.stroke();
    ctx.lineWidth = 1;
    return;
  }
  const x = X(pts[0][0]), y = Y(pts[0][1]);
  if (m.radius !== null) {
    ctx.globalAlpha = m.kind === "obstacle" ? 0.5 : 0.25;
    ctx.beginPath(); ctx.arc(x, y, Math.max(m.radius * s, 2), 0, 2 * Math.PI); ctx.fill();
    ctx.globalAlpha = 1;
  }
  ctx.beginPath();
  if (m.kind === "goal" || m.kind === "waypoint") {
    ctx.lineWidth = 2.5;
    ctx.moveTo(x - 5, y - 5); ctx.lineTo(x + 5, y + 5); ctx.moveTo(x - 5, y + 5); ctx.lineTo(x + 5, y - 5); ctx.stroke();
  } else if (m.kind === "keyframe") {
    ctx.moveTo(x, y - 5); ctx.lineTo(x + 4.5, y + 3.5); ctx.lineTo(x - 4.5, y + 3.5); ctx.closePath(); ctx.stroke();
  } else if (m.kind === "start") {
    ctx.strokeRect(x - 4, y - 4, 8, 8);
  } else if (m.kind === "object") {
    ctx.arc(x, y, 4, 0, 2 * Math.PI); ctx.stroke();
  } else {
    ctx.arc(x, y, 3, 0, 2 * Math.PI); ctx.fill();
  }
  ctx.lineWidth = 1;
  if (m.yaw !== null && (m.kind === "keyframe" || m.kind === "start")) {
    ctx.beginPath(); ctx.moveTo(x, y); ctx.lineTo(x + 12 * Math.cos(m.yaw), y - 12 * Math.sin(m.yaw)); ctx.stroke();
  }
  if (m.kind === "goal" || m.kind === "waypoint" || m.kind === "object") {  // labelled, kept inside the canvas
    const tw = ctx.measureText(m.label).width;
    ctx.fillText(m.label, x + 6 + tw > ctx.canvas.width ? x - 6 - tw : x + 6, y < 14 ? y + 14 : y - 6);
  }
}

function renderPath(i) {
  const canvas = $("path");
  const ctx = canvas.getContext("2d");
  const w = canvas.width, h = canvas.height;
  ctx.clearRect(0, 0, w, h);
  const xy = S.machine.xy;
  if (!xy) {
    $("path-note").textContent = "(the run's world records no ground-truth x/y)";
    return;
  }
  const cps = Object.values(S.machine.control_points || {});
  const bodies = (S.machine.bodies || []).filter((b) => S.col[b.x] !== undefined && S.col[b.y] !== undefined);
  const r = S.rows[i];
  const cpNow = controlPointOf(r[1]);
  const kinds = [...new Set(S.machine.markers.map((m) => m.kind))];
  $("path-note").textContent = `(ground truth ${xy[0].slice(3)}, ${xy[1].slice(3)} in m; ` +
    `drawn now: ${cpNow ? cpNow.label : "the robot pose"}` + (cps.length ? ", the robot pose in grey" : "") +
    (kinds.length ? "; markers: " + kinds.join(", ") : "; no markers declared") +
    (bodies.length ? "; squares: " + bodies.map((b) => b.name).join(", ") : "") + ")";
  const track = S.rows.map(controlAt);
  const poses = S.rows.map(poseAt);
  let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
  const grow = (x, y) => { if (x === null || y === null) return; x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y); };
  for (const p of track) if (p) grow(p[0], p[1]);
  for (const p of poses) if (p) grow(p[0], p[1]);
  const bodyAt = (b, row) => { const bx = row[S.col[b.x]], by = row[S.col[b.y]]; return bx === null || by === null ? null : [bx, by]; };
  for (const b of bodies) for (const row of [S.rows[0], r]) { const p = bodyAt(b, row); if (p) grow(p[0], p[1]); }
  for (const m of S.machine.markers) for (const p of m.points) { const q = m.radius || 0; grow(p[0] - q, p[1] - q); grow(p[0] + q, p[1] + q); }
  if (!Number.isFinite(x0)) return;
  const pad = 20;
  // one scale for x and y (a metre is a metre both ways), at least 0.5 m shown
  const s = Math.min((w - 2 * pad) / Math.max(x1 - x0, 0.5), (h - 2 * pad) / Math.max(y1 - y0, 0.5));
  const cx = (x0 + x1) / 2, cy = (y0 + y1) / 2;
  const X = (x) => w / 2 + (x - cx) * s;
  const Y = (y) => h / 2 - (y - cy) * s;
  // scale bar
  const most = (w / 4) / s;  // a 1, 2 or 5 × 10^k m bar of at most a quarter of the width
  const decade = Math.pow(10, Math.floor(Math.log10(most)));
  const unit = [5, 2, 1].map((f) => f * decade).find((u) => u <= most) || decade;
  ctx.strokeStyle = "#555"; ctx.fillStyle = "#555"; ctx.font = "10px sans-serif";
  ctx.beginPath(); ctx.moveTo(8, h - 8); ctx.lineTo(8 + unit * s, h - 8); ctx.stroke();
  ctx.fillText(`${unit} m`, 10, h - 11);
  for (const m of S.machine.markers) drawMarker(ctx, m, X, Y, s);
  // a polyline of points per row, broken where a point is missing or the drawn control point changes
  const line = (pts, from, to, color, width) => {
    ctx.strokeStyle = color; ctx.lineWidth = width; ctx.beginPath();
    let pen = false, cpPrev;
    for (let k = from; k <= to; k++) {
      const p = pts[k], cp = pts === track ? controlPointOf(S.rows[k][1]) : null;  // the pose never jumps
      if (!p || (pen && cp !== cpPrev)) pen = false;
      if (!p) continue;
      if (pen) ctx.lineTo(X(p[0]), Y(p[1])); else ctx.moveTo(X(p[0]), Y(p[1]));
      pen = true; cpPrev = cp;
    }
    ctx.stroke(); ctx.lineWidth = 1;
  };
  if (cps.length) line(poses, 0, S.rows.length - 1, "#9e9e9e", 1);  // the reported pose (the rear axle)
  line(track, 0, S.rows.length - 1, "#cfd8dc", 1);
  line(track, 0, i, "#1565c0", 2);
  ctx.fillStyle = "#6a1b9a";
  for (const b of bodies) {
    const p = bodyAt(b, r);
    if (!p) continue;
    ctx.fillRect(X(p[0]) - 4, Y(p[1]) - 4, 8, 8);
    ctx.fillText(b.name, X(p[0]) + 6, Y(p[1]) + 4);
  }
  const pose = poses[i], at = track[i];
  if (!pose || !at) return;
  if (at[0] !== pose[0] || at[1] !== pose[1]) {  // the robot pose, and the control point rigidly attached to it
    ctx.strokeStyle = "#757575"; ctx.fillStyle = "#757575";
    ctx.beginPath(); ctx.moveTo(X(pose[0]), Y(pose[1])); ctx.lineTo(X(at[0]), Y(at[1])); ctx.stroke();
    ctx.beginPath(); ctx.arc(X(pose[0]), Y(pose[1]), 3, 0, 2 * Math.PI); ctx.fill();
  }
  ctx.fillStyle = "#c62828";
  ctx.beginPath(); ctx.arc(X(at[0]), Y(at[1]), 5, 0, 2 * Math.PI); ctx.fill();
  if (pose[2] !== null) {  // heading
    ctx.strokeStyle = "#c62828"; ctx.lineWidth = 2; ctx.beginPath(); ctx.moveTo(X(at[0]), Y(at[1]));
    ctx.lineTo(X(at[0]) + 16 * Math.cos(pose[2]), Y(at[1]) - 16 * Math.sin(pose[2])); ctx.stroke(); ctx.lineWidth = 1;
  }
}

// -- camera frames -----------------------------------------------------------------------------------------
// The frames the run recorded (taskflow/execution/frames.py, in rendered modes): per camera, the one captured nearest the
// cursor's time, or the latest while following a live run; the image comes from /view/frame.
function nearestFrame(sensor, t, latest) {
  let best = null;
  for (const f of S.frames) {
    if (f.sensor !== sensor) continue;
    if (best === null || latest || Math.abs(f.stamp - t) < Math.abs(best.stamp - t) - 1e-12) best = f;
  }
  return best;
}

function renderCameras(t, latest) {
  const sensors = [...new Set(S.frames.map((f) => f.sensor))];
  $("camera-note").textContent = sensors.length
    ? `(recorded frame nearest the cursor${latest ? "; following: the latest" : ""}, per camera)`
    : "(no camera frames in this run: they are recorded in rendered perception modes, taskflow run --frames HZ)";
  for (const sensor of sensors) {
    let cam = S.cams[sensor];
    if (!cam) {
      const fig = document.createElement("figure");
      fig.className = "camera";
      const img = document.createElement("img");
      img.className = "frame";
      img.dataset.sensor = sensor;
      img.alt = `camera ${sensor}`;
      const cap = document.createElement("figcaption");
      fig.append(img, cap);
      $("cameras").appendChild(fig);
      cam = S.cams[sensor] = { img, cap, file: null };
    }
    const f = nearestFrame(sensor, t, latest);
    if (!f || f.file === cam.file) continue;
    cam.file = f.file;
    cam.img.dataset.stamp = String(f.stamp);
    cam.img.src = withToken(`view/frame?sensor=${encodeURIComponent(sensor)}&t=${f.stamp}`);
    cam.cap.textContent = `${sensor} (${f.frame}, ${f.width}×${f.height}) captured at t = ${f.stamp.toFixed(3)} s, tick ${f.tick}`;
  }
}

// -- data --------------------------------------------------------------------------------------------------
async function pull() {
  for (;;) {
    const tr = await getJSON(`view/trace?since=${S.rowNext}`);
    if (tr.columns.length && !S.cols.length) {
      S.cols = tr.columns;
      tr.columns.forEach((c, k) => { S.col[c] = k; });
      if (!S.machine.columns_known) {  // a live run: the ground-truth columns are known from now on
        const m = await getJSON("view/machine");
        Object.assign(S.machine, { xy: m.xy, bodies: m.bodies, markers: m.markers, control_points: m.control_points,
          columns_known: m.columns_known });
        S.cpOf.clear();
      }
      setupPlots();
    }
    for (const r of tr.rows) S.rows.push(r);
    S.rowNext = tr.next;
    if (tr.done) break;
  }
  const rec = await getJSON(`view/transitions?since=${S.recNext}`);
  for (const r of rec.records) S.recs.push(r);
  S.recNext = rec.next;
  const fr = await getJSON(`view/frames?since=${S.frameNext}`);
  for (const f of fr.records) S.frames.push(f);
  S.frameNext = fr.next;
}

function setupPlots() {
  const wanted = [];
  for (const tr of allTransitions()) if (tr.guard) guardMetrics(tr.guard.tree, wanted);
  [...new Set(wanted)].slice(0, 6).forEach(addPlot);
  const sel = $("add-metric");
  Object.keys(S.machine.metric_units).forEach((m) => {
    if (S.col["m." + m] === undefined) return;
    const o = document.createElement("option");
    o.value = m; o.textContent = m;
    sel.appendChild(o);
  });
}

async function livePoll() {
  try {
    const st = await getJSON("state");
    S.running = st.running;
    const mode = st.outcome ? `ended: ${st.outcome}` : st.paused ? "paused" : st.held ? "held" : "running";
    $("live-state").textContent = `run: ${st.state} at ${(+st.t).toFixed(2)} s — ${mode}`;
    $("live-state").dataset.t = String(st.t);
    $("live-state").dataset.mode = mode;
    await pull();
    if (S.follow) S.cursor = S.rows.length - 1;
    if (!S.running) S.summary = await getJSON("view/summary");
    render();
  } catch (e) {
    $("live-state").textContent = S.running ? `the run's server does not answer (${e.message})`
      : `the run has ended (${(S.summary && S.summary.outcome) || "?"}) and closed its server: replay it with taskflow view RUN_DIR`;
    return;
  }
  // after the run ends, poll on until its server closes: the record's last rows are written after the outcome
  setTimeout(livePoll, 400);
  if (!S.running) $("operator").querySelectorAll("button").forEach((b) => { b.disabled = true; });
}

async function operate(action) {
  const body = { who: "view" };
  if (action === "preempt" && $("preempt-to").value) body.to = $("preempt-to").value;
  if (action === "inject") body.event = $("inject-event").value;
  try {
    const r = await fetch(`${action}`, { method: "POST", headers: { "Content-Type": "application/json", ...authHeaders() }, body: JSON.stringify(body) });
    const j = await r.json();
    $("op-msg").textContent = r.ok ? `${j.queued} queued by ${j.who}` : `refused: ${j.error}`;
  } catch (e) {
    $("op-msg").textContent = `no answer: ${e.message}`;
  }
}

function seek(i) {
  S.cursor = Math.max(0, Math.min(S.rows.length - 1, i));
  render();
}

function stopFollowing() {
  S.follow = false;
  $("follow").checked = false;
}

function stepTransition(dir) {
  stopFollowing();
  const t = S.rows[S.cursor][0];
  const times = S.recs.filter((r) => r.to && r.cause !== "start").map((r) => r.t);
  // a transition fired at tick t shows from the next row on
  const target = dir > 0 ? times.find((x) => x >= t) : [...times].reverse().find((x) => x < t - 1e-9 && S.rows.findIndex((r) => r[0] > x) < S.cursor);
  if (target === undefined) return;
  const k = S.rows.findIndex((r) => r[0] > target + 1e-9);
  seek(k < 0 ? S.rows.length - 1 : k);
}

function wire() {
  $("timeline").addEventListener("input", (e) => { stopFollowing(); seek(+e.target.value); });
  $("prev-row").onclick = () => { stopFollowing(); seek(S.cursor - 1); };
  $("next-row").onclick = () => { stopFollowing(); seek(S.cursor + 1); };
  $("next-tr").onclick = () => stepTransition(1);
  $("prev-tr").onclick = () => stepTransition(-1);
  $("follow").onchange = (e) => { S.follow = e.target.checked; if (S.follow) seek(S.rows.length - 1); };
  $("add-metric").onchange = (e) => { if (e.target.value) { addPlot(e.target.value); render(); } e.target.value = ""; };
  $("play").onclick = () => {
    if (S.playing) { clearInterval(S.playing); S.playing = null; return; }
    stopFollowing();
    const step = Math.max(1, Math.round(S.machine.rate_hz * 0.05));
    S.playing = setInterval(() => {
      if (S.cursor >= S.rows.length - 1) { clearInterval(S.playing); S.playing = null; return; }
      seek(S.cursor + step);
    }, 50);
  };
  for (const a of ["pause", "hold", "resume", "preempt", "inject"]) $(`op-${a}`).onclick = () => operate(a);
}

async function main() {
  S.machine = await getJSON("view/machine");
  S.live = S.machine.live;
  index(S.machine.root, null);
  buildChart(S.machine.root, $("chart"), false);
  $("mission").textContent = S.machine.mission;
  document.title = `${S.machine.mission} — taskflow view`;
  $("mode").textContent = S.live ? "live" : "replay";
  if (IN_CAMPAIGN) { $("campaign-link").href = withToken("/"); $("campaign-link").hidden = false; }
  $("mode").classList.toggle("live", S.live);
  wire();
  if (S.live) {
    $("operator").hidden = false;
    const m = await getJSON("mission");
    m.states.forEach((s) => { const o = document.createElement("option"); o.value = s; o.textContent = s; $("preempt-to").appendChild(o); });
    m.events.forEach((ev) => { const o = document.createElement("option"); o.value = ev; o.textContent = ev; $("inject-event").appendChild(o); });
    livePoll();
  } else {
    $("follow-label").hidden = true;
    S.follow = false;
    await pull();
    S.summary = await getJSON("view/summary");
    const st = S.summary;
    $("live-state").textContent = st.outcome ? `outcome: ${st.outcome} (${st.reason || ""}) in ${st.final_state}` : "";
    S.cursor = 0;
    render();
  }
  document.body.dataset.ready = "1";
}

window.taskflowView = { S, seek, render, controlAt };
main().catch((e) => { document.body.dataset.error = e.message; $("live-state").textContent = `error: ${e.message}`; });
