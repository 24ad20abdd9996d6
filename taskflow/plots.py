"""Paper-style figures of a run directory, as PNG (matplotlib, no display needed).

* ``path.png`` — top view of the ground-truth path (``gt.x``/``gt.y``, or ``gt.NAME_x``/``_y``),
  coloured by state, with the world's target (``gt.target_x``/``gt.target_y``) when recorded;
* ``commands.png`` — every command component over time, states as coloured bands;
* ``camera_velocities.png`` — the camera twist, when the task publishes ``cam_v*`` / ``cam_w*``;
* ``metrics.png`` — every other published metric over time, states as bands.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .records import read_trace


def _bands(ax, t: np.ndarray, states: np.ndarray, colours: dict[str, tuple]) -> None:  # type: ignore[no-untyped-def]
    if t.size == 0:
        return
    start = 0
    for i in range(1, t.size + 1):
        if i == t.size or states[i] != states[start]:
            end_t = t[i] if i < t.size else t[-1]
            ax.axvspan(t[start], end_t, color=colours[states[start]], alpha=0.15, lw=0)
            start = i


def _stacked(plt, tr: dict[str, np.ndarray], cols: list[str], prefix: int, colours: dict[str, tuple],  # type: ignore[no-untyped-def]
             title: str, path: Path, legend: bool = False) -> Path:
    """One panel per column over time, the states as coloured bands; saved to ``path``."""
    t, states = tr["t"], tr["state"]
    fig, axes = plt.subplots(len(cols), 1, figsize=(8, 1.7 * len(cols) + 0.6), sharex=True, squeeze=False)
    for ax, c in zip(axes[:, 0], cols):
        _bands(ax, t, states, colours)
        ax.plot(t, tr[c], lw=1.2)
        ax.set_ylabel(c[prefix:], fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("t [s]")
    axes[0, 0].set_title(title)
    if legend:
        handles = [plt.Rectangle((0, 0), 1, 1, color=colours[s], alpha=0.3) for s in colours]
        fig.legend(handles, list(colours), loc="lower center", ncol=min(4, len(colours)), fontsize=7)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def _target_of(run_dir: Path) -> tuple[float, float] | None:
    """The world position of the run's object, when the world reports one in the summary
    (``object_world_x_m`` / ``object_world_y_m``)."""
    import json

    try:
        m = json.loads((run_dir / "summary.json").read_text()).get("metrics", {})
        return float(m["object_world_x_m"]), float(m["object_world_y_m"])
    except (OSError, KeyError, TypeError, ValueError):
        return None


def plot_run(run_dir: str | Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run_dir = Path(run_dir)
    tr = read_trace(run_dir)
    t, states = tr["t"], tr["state"]
    names = list(dict.fromkeys(states.tolist()))
    cmap = plt.get_cmap("tab10")
    colours = {s: cmap(i % 10) for i, s in enumerate(names)}
    out: list[Path] = []

    # path
    xk, yk = ("gt.x", "gt.y") if "gt.x" in tr else ("gt.robot_x", "gt.robot_y")
    if xk in tr and yk in tr:
        fig, ax = plt.subplots(figsize=(6, 6))
        x, y = tr[xk], tr[yk]
        for s in names:
            m = states == s
            ax.plot(x[m], y[m], ".", ms=2, color=colours[s], label=s)
        target = _target_of(run_dir)
        if target is not None:
            ax.plot(*target, "k*", ms=14, label="object")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title("ground-truth path by state")
        ax.legend(fontsize=7, markerscale=4)
        ax.grid(alpha=0.3)
        out.append(run_dir / "path.png")
        fig.savefig(out[-1], dpi=110, bbox_inches="tight")
        plt.close(fig)

    # commands
    cmd_cols = [c for c in tr if c.startswith("cmd.")]
    if cmd_cols:
        out.append(_stacked(plt, tr, cmd_cols, 4, colours, "commands (state bands)", run_dir / "commands.png"))

    # camera velocities (tasks that publish cam_v*/cam_w*), one panel each for linear and angular
    cam = [c for c in tr if c.startswith("m.cam_") and np.isfinite(tr[c]).any()]
    if cam:
        fig, axes = plt.subplots(2, 1, figsize=(8, 4.5), sharex=True)
        for ax, kind, unit in ((axes[0], "m.cam_v", "m/s"), (axes[1], "m.cam_w", "rad/s")):
            _bands(ax, t, states, colours)
            for c in cam:
                if c.startswith(kind):
                    ax.plot(t, tr[c], lw=1.2, label=c[6:])
            ax.set_ylabel(unit)
            ax.legend(fontsize=7, ncol=3)
            ax.grid(alpha=0.3)
        axes[0].set_title("camera velocities (state bands)")
        axes[1].set_xlabel("t [s]")
        out.append(run_dir / "camera_velocities.png")
        fig.savefig(out[-1], dpi=110, bbox_inches="tight")
        plt.close(fig)

    # metrics
    m_cols = [c for c in tr if c.startswith("m.") and not c.startswith("m.cam_") and np.isfinite(tr[c]).any()]
    if m_cols:
        out.append(_stacked(plt, tr, m_cols, 2, colours, "metrics (state bands)", run_dir / "metrics.png",
                            legend=True))
    return out
