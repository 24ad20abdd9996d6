// taskflow view BATCH_DIR: the page of a campaign, drawn from its batch.json (taskflow/operate/campaign_view.py
// serves it). Every figure is batch.json's own (taskflow/campaigns/batch.py computed it): the page formats, it
// does not recompute. Plain JavaScript, no library (common.js loaded first); the record's strings are set as
// text, never as markup.
"use strict";

const pct = (x) => (x === null || x === undefined ? "–" : (100 * x).toFixed(1));
const num = (x) => (x === null || x === undefined ? "–" : Math.abs(x) >= 1e4 || (Math.abs(x) < 1e-3 && x !== 0) ? x.toExponential(4) : (+x.toPrecision(5)).toString());

async function getJSON(url) {
  const r = await fetch(withToken(url), { cache: "no-store" });
  const j = await r.json().catch(() => ({}));
  if (!r.ok) throw new Error(j.error || `${url}: HTTP ${r.status}`);
  return j;
}

function rowOf(tbody, cells) {
  const tr = document.createElement("tr");
  cells.forEach((c) => cell(tr, c));
  tbody.appendChild(tr);
  return tr;
}

// "k/n = r % [lo, hi]", as taskflow batch prints it; the numbers on the element as data-* (rate, low, high)
function rate(td, k, n, r, ci) {
  td.textContent = `${k}/${n}` + (r !== null && r !== undefined ? ` = ${pct(r)} %` : "") + (ci ? ` [${pct(ci[0])}, ${pct(ci[1])}]` : "");
  td.classList.add("rate");
  td.dataset.k = String(k);
  td.dataset.n = String(n);
  td.dataset.rate = r === null || r === undefined ? "" : String(r);
  td.dataset.low = ci ? String(ci[0]) : "";
  td.dataset.high = ci ? String(ci[1]) : "";
  return td;
}

const successOf = (agg) => [agg.outcomes.succeeded || 0, agg.trials, agg.success_rate, agg.success_ci95];
const violationOf = (p) => [p.violated, p.held + p.violated, p.violation_rate, p.violation_ci95];

function showSuccess(agg) {
  const tb = $("success").tBodies[0];
  const tr = rowOf(tb, ["succeeded"]);
  rate(cell(tr, ""), ...successOf(agg)).id = "success-rate";
  const out = rowOf(tb, ["outcomes"]);
  const td = cell(out, Object.entries(agg.outcomes).map(([o, k]) => `${o} ${k}`).join(", "));
  td.id = "outcomes";
  td.dataset.outcomes = JSON.stringify(agg.outcomes);
  const items = Object.entries(agg.items || {});
  $("items-head").hidden = $("items").hidden = !items.length;
  for (const [loop, c] of items) {
    const r = rowOf($("items").tBodies[0], [loop]);
    rate(cell(r, ""), c.succeeded, c.attempted, c.success_rate, c.success_ci95).dataset.loop = loop;
    cell(r, c.rule || "");
  }
}

function showProperties(props) {
  const names = Object.keys(props);
  $("properties-head").hidden = $("properties").hidden = !names.length;
  for (const name of names) {
    const p = props[name];
    const tr = rowOf($("properties").tBodies[0], [name, p.pattern, String(p.held), String(p.violated), String(p.not_decided)]);
    tr.dataset.property = name;
    rate(cell(tr, "", p.violated ? "no" : "ok"), ...violationOf(p)).classList.add("violation");
    cell(tr, p.first_violation_t === undefined || p.first_violation_t === null ? "–" : `t = ${num(p.first_violation_t)} s`);
  }
  return names;
}

function showConditions(conditions, names) {
  if (conditions.length < 2) return;
  $("conditions-head").hidden = $("conditions").hidden = false;
  const head = document.createElement("tr");
  ["condition", "trials", "succeeded"].concat(names.map((n) => `${n} violated`)).forEach((h) => {
    const th = document.createElement("th"); th.textContent = h; head.appendChild(th);
  });
  $("conditions").tHead.appendChild(head);
  for (const c of conditions) {
    const agg = c.aggregate;
    const tr = rowOf($("conditions").tBodies[0], [`${c.index}: ${c.label}`, String(agg.trials)]);
    tr.dataset.condition = String(c.index);
    rate(cell(tr, ""), ...successOf(agg)).classList.add("success");
    for (const n of names) {
      const p = (agg.properties || {})[n];
      const td = p ? rate(cell(tr, ""), ...violationOf(p)) : cell(tr, "–");
      td.dataset.property = n;
    }
  }
}

function showMetrics(metrics) {
  for (const [k, m] of Object.entries(metrics)) {
    const tr = rowOf($("metrics").tBodies[0], [k, num(m.mean), m.ci95 ? `[${num(m.ci95[0])}, ${num(m.ci95[1])}]` : "–",
      num(m.std), num(m.min), num(m.max), String(m.n)]);
    tr.dataset.metric = k;
    tr.dataset.mean = String(m.mean);
  }
}

function showTrials(c, names) {
  const head = document.createElement("tr");
  ["seed", "condition", "outcome", "sim time (s)"].concat(names, ["replay"]).forEach((h) => {
    const th = document.createElement("th"); th.textContent = h; head.appendChild(th);
  });
  $("trials").tHead.appendChild(head);
  for (const t of c.trials) {
    const tr = rowOf($("trials").tBodies[0], [String(t.seed), String(t.condition)]);
    tr.dataset.seed = String(t.seed);
    tr.dataset.condition = String(t.condition);
    cell(tr, t.outcome, t.outcome === "succeeded" ? "ok" : "no").title = t.reason || "";
    cell(tr, num(t.sim_time_s));
    for (const n of names) {
      const v = t.properties[n];
      const td = cell(tr, v ? v.verdict.replace("_", " ") + (v.verdict === "violated" && v.t !== null ? ` at ${num(v.t)} s` : "") : "–",
        v && v.verdict === "violated" ? "no" : v && v.verdict === "held" ? "ok" : "");
      td.dataset.property = n;
      td.dataset.verdict = v ? v.verdict : "";
    }
    const td = cell(tr, "");
    if (t.replay) {
      const a = document.createElement("a");
      a.href = withToken(t.replay);
      a.textContent = "replay";
      a.className = "replay";
      td.appendChild(a);
    } else if (t.run_error) {
      td.textContent = "no replay";
      td.title = t.run_error;
      td.className = "muted";
    }
  }
  $("kept-note").textContent = c.kept ? `(${c.kept} of ${c.trials.length} run folders kept: replay links)`
    : "(no run folders kept: taskflow batch --keep-runs keeps them, for a replay of each)";
}

async function main() {
  const c = await getJSON("campaign");
  $("mission").textContent = c.mission;
  document.title = `${c.mission} — taskflow campaign`;
  const asked = c.trials_requested === null || c.trials_requested === undefined ? "" : ` of ${c.trials_requested * Math.max(1, c.conditions.length)} asked`;
  $("trial-count").textContent = `${c.aggregate.trials} trials${asked}` + (c.conditions.length > 1 ? `, ${c.conditions.length} conditions` : "");
  $("trial-count").dataset.trials = String(c.aggregate.trials);
  $("interrupted").hidden = !c.interrupted;
  document.body.dataset.interrupted = String(c.interrupted);
  $("folder").textContent = c.folder;
  showSuccess(c.aggregate);
  const names = showProperties(c.aggregate.properties || {});
  showConditions(c.conditions, names);
  showMetrics(c.aggregate.metrics);
  showTrials(c, names);
  document.body.dataset.ready = "1";
}

main().catch((e) => { document.body.dataset.error = e.message; $("folder").textContent = `error: ${e.message}`; });
