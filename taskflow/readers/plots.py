"""Paper-style figures of a run directory, as PNG (matplotlib, no display needed).

* ``path.png`` — top view of the ground truth: the point each state's guards measure (the car's control
  point ``d`` ahead of the rear axle, :class:`~taskflow.markers.ControlPoint`) coloured by state, the
  robot's reported pose (the rear axle) in grey, other bodies (the object, the part) dashed, and the
  scene the world and tasks declare (goals, waypoints, keyframes, obstacles, walls, start);
* ``commands.png`` — every command component over time, labelled with its name and unit as the robot
  declares them (:attr:`~taskflow.api.Robot.command_units`);
* ``camera_velocities.png`` — the camera twist, when the task publishes ``cam_v*`` / ``cam_w*``;
* ``metrics.png`` — every other published metric with its unit, each guard's threshold on it as a
  horizontal line.

Every time plot marks each transition with a vertical line and the name of the state entered, each
operator action (``taskflow ctl``, an operator script) with a purple dash-dotted line named at the foot
of the top panel (``pause, hold (ann)``), and the states as faint bands; legends sit outside the axes
so they never cover data.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from taskflow.execution.records import RETRY
from taskflow.markers import Marker
from taskflow.readers.recorded import RecordedRun, Threshold, load_run

UNITLESS = "-"
"""Axis unit shown for a dimensionless metric."""

_ROLE_STYLE: dict[str, dict[str, Any]] = {
    "goal": {"marker": "X", "color": "crimson", "ms": 11},
    "waypoint": {"marker": "X", "color": "crimson", "ms": 11},
    "keyframe": {"marker": "^", "color": "darkorange", "ms": 6},
    "object": {"marker": "o", "color": "black", "ms": 7},
    "start": {"marker": "s", "color": "dimgray", "ms": 7},
    "obstacle": {"marker": "o", "color": "seagreen", "ms": 8},
    "boundary": {"marker": "", "color": "black", "ms": 0},
}


def axis_label(name: str, unit: str) -> str:
    """``"pos_error [m]"``; a dimensionless quantity is shown ``[-]``."""
    return f"{name} [{unit or UNITLESS}]"


def _colours(run: RecordedRun) -> dict[str, Any]:
    import matplotlib

    names = list(dict.fromkeys(run.trace["state"].tolist()))
    cmap = matplotlib.colormaps["tab10"]
    return {s: cmap(i % 10) for i, s in enumerate(names)}


def _bands(ax: Any, t: np.ndarray, states: np.ndarray, colours: dict[str, Any]) -> None:
    start = 0
    for i in range(1, t.size + 1):
        if i == t.size or states[i] != states[start]:
            end_t = t[i] if i < t.size else t[-1]
            ax.axvspan(t[start], end_t, color=colours[states[start]], alpha=0.08, lw=0)
            start = i


def _short(path: str) -> str:
    return path.rsplit(".", 1)[-1]


def _transition_labels(run: RecordedRun) -> list[tuple[float, str]]:
    """(t, text) per group of transitions closer than 2.5 % of the run: the states entered, in order
    (``"reached → approach"`` when an item ends and the next begins on one tick)."""
    span = float(run.trace["t"][-1] - run.trace["t"][0]) if run.trace["t"].size else 1.0
    groups: list[tuple[float, list[str]]] = []
    for rec in run.transitions:
        if rec.cause == "start":
            continue
        name = _short(rec.target) + (f" (attempt {rec.attempt})" if rec.cause == RETRY else "")
        if groups and rec.t - groups[-1][0] <= 0.025 * span:
            if groups[-1][1][-1] != name:
                groups[-1][1].append(name)
        else:
            groups.append((rec.t, [name]))
    return [(t, " → ".join(names)) for t, names in groups]


OPERATOR_COLOUR = "purple"
"""Colour of the operator's actions on the time plots (their lines carry ``gid="operator"``)."""


def operator_labels(run: RecordedRun) -> list[tuple[float, str]]:
    """(t, text) per tick at which operator actions took effect: ``"pause, hold, resume (ann, script)"``,
    a pre-emption with its target (``"preempt → home (bob)"``), an injection with its event."""
    groups: dict[float, list[tuple[str, str]]] = {}
    for op in run.operator:
        what = {"preempt": f"preempt → {_short(op.args['to'])}" if op.args.get("to") else "preempt (abort)",
                "inject": f"inject {op.args.get('event', '')}"}.get(op.action, op.action)
        groups.setdefault(op.t, []).append((what, op.who))
    return [(t, ", ".join(w for w, _ in acts) + f" ({', '.join(dict.fromkeys(who for _, who in acts))})")
            for t, acts in groups.items()]


def _transition_lines(ax: Any, run: RecordedRun, label: bool) -> None:
    """A vertical line at each transition and operator action; on the top panel (``label``) the states
    entered are named above it and the operator's actions at its foot."""
    for rec in run.transitions:
        if rec.cause != "start":
            ax.axvline(rec.t, color="black", lw=0.7, ls=":", alpha=0.8)
    for t, text in operator_labels(run):
        ax.axvline(t, color=OPERATOR_COLOUR, lw=1.0, ls="-.", alpha=0.9, gid="operator")
        if label:
            ax.annotate(text, xy=(t, 0.0), xycoords=("data", "axes fraction"), xytext=(2, 2),
                        textcoords="offset points", rotation=90, fontsize=6.5, ha="left", va="bottom",
                        color=OPERATOR_COLOUR, gid="operator")
    if label:
        for t, text in _transition_labels(run):
            ax.annotate(text, xy=(t, 1.0), xycoords=("data", "axes fraction"), xytext=(2, 2),
                        textcoords="offset points", rotation=60, fontsize=6.5, ha="left", va="bottom")


def threshold_text(th: Threshold, unit: str, where: list[Threshold] | None = None) -> str:
    """``"feature_error < 2 px (forward → rotate)"``: the comparison in the metric's base unit (an angle also
    in degrees) and the transitions it guards (``where``, default: ``th``'s own; at most two named)."""
    import math

    metric = f"|{th.metric}|" if th.absolute else th.metric
    value = f"{th.value:.4g} {unit}".rstrip() + (f" ({math.degrees(th.value):.3g} deg)" if unit == "rad" else "")
    where = where or [th]
    names = [f"{_short(o.source)} → {_short(o.target)}" for o in where[:2]]
    more = f" +{len(where) - 2} more" if len(where) > 2 else ""
    return f"{metric} {th.op} {value} ({', '.join(names)}{more})"


Panel = tuple[str, list[tuple[np.ndarray, str]], str, list[Threshold]]
"""One time plot: y label, [(values, legend label)], unit, the guard thresholds drawn on it."""


def time_figure(run: RecordedRun, panels: list[Panel], title: str) -> Figure:
    """One panel per entry over time, with state bands, transition lines and threshold lines."""
    from matplotlib.patches import Rectangle

    t, states = run.trace["t"], run.trace["state"]
    colours = _colours(run)
    run_ths = run.thresholds()
    fig = Figure(figsize=(9, 1.8 * len(panels) + 1.2))
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)
    for k, (ax, (ylabel, series, unit, ths)) in enumerate(zip(axes[:, 0], panels)):
        _bands(ax, t, states, colours)
        for values, lab in series:
            ax.plot(t, values, lw=1.2, label=lab or None)
        for th in ths:
            where = [o for o in run_ths if (o.metric, o.op, o.value) == (th.metric, th.op, th.value)]
            ax.axhline(th.value, color="crimson", lw=1.0, ls="--", label=f"guard: {threshold_text(th, unit, where)}")
            if th.absolute:
                ax.axhline(-th.value, color="crimson", lw=1.0, ls="--")
        _transition_lines(ax, run, label=k == 0)
        ax.set_ylabel(ylabel, fontsize=8)
        ax.grid(alpha=0.3)
        if len(series) > 1 or ths:
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, borderaxespad=0.0)
    axes[-1, 0].set_xlabel("t [s]")
    longest = max((len(text) for _, text in _transition_labels(run)), default=0)
    axes[0, 0].set_title(title, pad=10 + 3.2 * min(longest, 60))
    handles = [Rectangle((0, 0), 1, 1, color=colours[s], alpha=0.3) for s in colours]
    fig.legend(handles, [f"state {s}" for s in colours], loc="upper center", bbox_to_anchor=(0.5, -0.45),
               bbox_transform=axes[-1, 0].transAxes, ncol=min(4, len(colours)), fontsize=7)
    return fig


def _draw_marker(ax: Any, m: Marker, labelled: set[str]) -> None:
    style = _ROLE_STYLE[m.role]
    legend = (m.label if m.role == "object" else m.role) if m.role not in labelled else None
    labelled.add(m.role)
    xs, ys = [p[0] for p in m.points], [p[1] for p in m.points]
    if m.closed:
        import matplotlib.patches as mpatches

        fill = m.role == "obstacle"
        ax.add_patch(mpatches.Polygon(list(m.points), closed=True, fill=fill, alpha=0.5 if fill else 1.0,
                                      color=style["color"], lw=1.2, label=legend))
        return
    if m.radius is not None:
        import matplotlib.patches as mpatches

        ax.add_patch(mpatches.Circle(m.points[0], m.radius, color=style["color"],
                                     alpha=0.5 if m.role == "obstacle" else 0.25, label=legend))
        legend = None
    if len(m.points) > 1:
        ax.plot(xs, ys, "-", color=style["color"], lw=1.0, label=legend)
        return
    ax.plot(xs, ys, style["marker"], color=style["color"], ms=style["ms"], mfc="none" if m.role == "keyframe" else None,
            mew=1.5, label=legend, zorder=5)
    if m.yaw is not None and m.role in ("keyframe", "start"):
        ax.annotate("", xy=(xs[0] + 0.12 * np.cos(m.yaw), ys[0] + 0.12 * np.sin(m.yaw)), xytext=(xs[0], ys[0]),
                    arrowprops={"arrowstyle": "->", "color": style["color"], "lw": 0.8})
    if m.role in ("goal", "waypoint"):
        ax.annotate(m.label, (xs[0], ys[0]), xytext=(6, 6), textcoords="offset points", fontsize=7,
                    color=style["color"])


def path_figure(run: RecordedRun) -> Figure | None:
    """The top view (module docstring); None when the world declares no pose."""
    bodies = list(run.scene.poses)
    robot = run.pose_track(bodies[0]) if bodies else None
    if robot is None:
        return None
    states = run.trace["state"]
    colours = _colours(run)
    cx, cy = run.control_track()
    fig = Figure(figsize=(7.5, 6))
    ax = fig.subplots()
    x, y, _ = robot
    cps = {cp.label for cp in run.scene.control_points.values()}
    ax.plot(x, y, "-", color="0.6", lw=1.0, label="robot pose (ground truth)" if cps else None, zorder=1)
    for s in colours:
        m = states == s
        cp = run.scene.control_point(s)
        what = cp.label if cp is not None else "robot pose"
        ax.plot(cx[m], cy[m], ".", ms=2.5, color=colours[s], label=f"{s}: {what}", zorder=3)
    for body in bodies[1:]:
        track = run.pose_track(body)
        if track is not None:
            ax.plot(track[0], track[1], "--", color="black", lw=1.0, label=f"{body} (ground truth)", zorder=2)
    labelled: set[str] = set()
    for mk in run.scene.markers:
        _draw_marker(ax, mk, labelled)
    for rec in run.transitions:  # where each transition fired: the last tick of the state it left
        i = int(np.searchsorted(run.trace["t"], rec.t)) - 1
        if rec.cause != "start" and 0 <= i < cx.size:
            ax.plot(cx[i], cy[i], "|", color="black", ms=9, mew=1.5, zorder=4,
                    label="transition" if "transition" not in labelled else None)
            labelled.add("transition")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{run.mission.name} (seed {run.seed}): top view, ground truth", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=7, markerscale=1.5, borderaxespad=0.0)
    return fig


def command_figure(run: RecordedRun) -> Figure | None:
    """Every command component with its declared name and unit; None when the trace has none."""
    cmd = [c for c in run.trace if c.startswith("cmd.")]
    if not cmd:
        return None
    panels: list[Panel] = []
    for c in cmd:
        name, unit = run.command_labels.get(c, (c[4:], "?"))
        panels.append((axis_label(name, unit), [(run.trace[c], "")], unit, []))
    return time_figure(run, panels, f"{run.mission.name}: commands ({run.mission.robot_cls.name})")


def camera_figure(run: RecordedRun) -> Figure | None:
    """The camera twist (``cam_v*``, ``cam_w*`` metrics); None when the task publishes none."""
    cam = [m for m in run.metric_columns() if m.startswith("cam_")]
    panels: list[Panel] = []
    for kind, what in (("cam_v", "camera linear velocity"), ("cam_w", "camera angular velocity")):
        cols = [m for m in cam if m.startswith(kind)]
        if cols:
            unit = run.metric_units.get(cols[0], "")
            panels.append((axis_label(what, unit), [(run.trace[f"m.{m}"], m) for m in cols], unit, []))
    return time_figure(run, panels, f"{run.mission.name}: camera velocities") if panels else None


def metrics_figure(run: RecordedRun) -> Figure | None:
    """Every other metric with its unit and the thresholds of the guards that read it."""
    ths = run.thresholds()
    panels: list[Panel] = []
    for m in run.metric_columns():
        if m.startswith("cam_"):
            continue
        unit = run.metric_units.get(m, "")
        seen: set[tuple[str, float]] = set()
        mine = []
        for th in ths:
            if th.metric == m and (th.op, th.value) not in seen:
                seen.add((th.op, th.value))
                mine.append(th)
        panels.append((axis_label(m, unit), [(run.trace[f"m.{m}"], "")], unit, mine))
    return time_figure(run, panels, f"{run.mission.name}: metrics, guard thresholds dashed") if panels else None


FIGURES = {"path": path_figure, "commands": command_figure, "camera_velocities": camera_figure,
           "metrics": metrics_figure}
"""File stem → the function drawing that figure."""


def plot_recorded(run: RecordedRun) -> list[Path]:
    """Write the figures of ``run`` into its directory as ``STEM.png``; returns their paths."""
    out: list[Path] = []
    for stem, draw in FIGURES.items():
        fig = draw(run)
        if fig is not None:
            out.append(run.dir / f"{stem}.png")
            fig.savefig(out[-1], dpi=110, bbox_inches="tight")
    return out


def plot_run(run_dir: str | Path) -> list[Path]:
    """The figures of the run directory ``run_dir`` (:class:`~taskflow.readers.recorded.RunDirError` if it is not one)."""
    return plot_recorded(load_run(run_dir))
