"""How ``screw_conveyor`` scores a run: the tool tip's errors to the part's bolts (ground truth, never
observed) and the summary of what happened at the part, per screwdriver operation (the mission's items
are the framework's to count).  Pure numpy over what the world hands in: no simulator.

The summary (:func:`summary_metrics`):

* ``operations`` — operations started (one per activation); ``operations_fastened``,
  ``operations_failed`` (of which ``operations_no_bolt`` found no bolt under the tool) and
  ``operations_unfinished`` (cancelled, interrupted or still running at the end);
* ``operation_log`` — per operation: ``operation`` (index), ``bolt`` (the bolt worked on, None when
  there was none), ``nearest_bolt`` and ``nearest_bolt_mm`` (tool tip → nearest bolt frame at the
  start), ``bolt_already_fastened``, ``t_start``, ``t_end``, ``outcome`` (``fastened``, ``failed``,
  ``cancelled``, ``interrupted``, or ``activating`` / ``coupled`` / ``fastening`` if the run ended
  first), ``failure`` (``no_bolt``, ``coupling``, ``slipped``, ``not_coupled`` or None),
  ``coupling_error_mm`` (largest lateral error during activation), ``err_t_mean_mm``,
  ``err_t_max_mm``, ``err_r_mean_deg``, ``err_r_max_deg`` and ``err_samples`` (tool tip to the
  operation's bolt, sampled every control tick while the screwdriver runs; None without a bolt),
  ``screwing_s`` (activation start → fastened);
* ``fastened_err_t_{min,max,mean}_mm``, ``fastened_err_r_{min,max,mean}_deg`` over the samples of the
  fastened operations only (``fastened_err_operations`` of them, ``fastened_err_samples`` samples);
  ``at_bolt_err_*`` the same over every operation that had a bolt (fastened, failed at the bolt,
  cancelled: ``at_bolt_err_operations``, ``at_bolt_err_samples``) — the paper's Table 2 measures all
  its screwing attempts; operations without a bolt have no bolt error and are in neither;
* ``screwing_time_mean_s`` over the fastened operations; ``bolts_on_part`` and ``bolts_fastened``
  (distinct bolts of the part fastened);
* ``final_base_speed_mps`` and ``final_arm_speed_radps`` (ground truth, as in the world's
  ``ground_truth``), ``final_part_x_m``; the marker pose error at capture against the truth
  (``perception_rms_xy_mm`` across the view, ``perception_rms_z_mm`` along it,
  ``perception_rms_r_deg``) — measured in the rendered mode, injected in the pose mode; in the rendered
  mode ``rendered_frames`` (images processed), ``rendered_searches`` (full-view searches) and
  ``rendered_dropped`` (frames the dropout skipped).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from taskflow_sim.screw.screwdriver import BitErrors, OperationLog

from taskflow.spatial import rotation_angle


def bit_errors(T_world_tip: NDArray[np.float64], T_world_bolts: Sequence[NDArray[np.float64]],
               bolt: int | None = None) -> tuple[int, BitErrors]:
    """The bolt (the nearest to the tip when ``bolt`` is None) and the tool tip's errors to its frame:
    distance, rotation, lateral offset from the bolt's axis, axial offset along it, tilt of the tool's
    axis against the bolt's (m and rad, ground truth)."""
    tip = T_world_tip
    if bolt is None:
        bolt = int(np.argmin([np.linalg.norm(b[:3, 3] - tip[:3, 3]) for b in T_world_bolts]))
    B = T_world_bolts[bolt]
    d = tip[:3, 3] - B[:3, 3]
    z = B[:3, 2]
    axial = float(d @ z)
    lateral = float(np.linalg.norm(d - axial * z))
    rot = rotation_angle(B[:3, :3].T @ tip[:3, :3])
    tilt = math.acos(max(-1.0, min(1.0, float(tip[:3, 2] @ z))))
    return bolt, BitErrors(float(np.linalg.norm(d)), rot, lateral, axial, tilt)


def operation_log(log: OperationLog) -> list[dict[str, Any]]:
    """The operations with their errors to their bolt (see the module docstring)."""
    out = []
    for op in log.ops:
        rec = op.record()
        t, r = np.array(op.err_t), np.array(op.err_r)
        rec["err_samples"] = int(len(t))
        rec["err_t_mean_mm"] = float(np.mean(t) * 1e3) if len(t) else None
        rec["err_t_max_mm"] = float(np.max(t) * 1e3) if len(t) else None
        rec["err_r_mean_deg"] = float(np.degrees(np.mean(r))) if len(r) else None
        rec["err_r_max_deg"] = float(np.degrees(np.max(r))) if len(r) else None
        out.append(rec)
    return out


def summary_metrics(log: OperationLog, bolts_on_part: int, ground_truth: Mapping[str, float] | None,
                    perception_errors: Sequence[tuple[float, float, float]],
                    rendered: Mapping[str, int] | None) -> dict[str, Any]:
    """The run's summary (module docstring): the screwdriver's ``log``, the part's bolt count, the final
    ``ground_truth`` (None: the world is closed), the marker's ``perception_errors`` at capture and the
    rendered detector's counts (``rendered_frames``, ``rendered_searches``, ``rendered_dropped``; None in
    the pose mode)."""
    ops = log.ops
    fastened = [i for i, op in enumerate(ops) if op.outcome == "fastened"]
    failed = [i for i, op in enumerate(ops) if op.outcome == "failed"]
    at_bolt = [i for i, op in enumerate(ops) if op.bolt is not None]
    out: dict[str, Any] = {
        "operations": len(ops),
        "operations_fastened": len(fastened),
        "operations_failed": len(failed),
        "operations_no_bolt": sum(1 for op in ops if op.failure == "no_bolt"),
        "operations_unfinished": len(ops) - len(fastened) - len(failed),
        "bolts_on_part": bolts_on_part,
        "bolts_fastened": len(log.bolts_done),
        "operation_log": operation_log(log),
    }
    for group, idx in (("fastened", fastened), ("at_bolt", at_bolt)):
        ts = np.array([x for i in idx for x in ops[i].err_t])
        rs = np.array([x for i in idx for x in ops[i].err_r])
        out[f"{group}_err_operations"] = len(idx)
        out[f"{group}_err_samples"] = int(len(ts))
        for name, arr, scale, unit in (("err_t", ts, 1e3, "mm"), ("err_r", rs, 180.0 / math.pi, "deg")):
            for stat, fn in (("min", np.min), ("max", np.max), ("mean", np.mean)):
                out[f"{group}_{name}_{stat}_{unit}"] = float(fn(arr) * scale) if len(arr) else None
    times = [s for i in fastened if (s := ops[i].screwing_s) is not None]  # every fastened operation has one
    out["screwing_time_mean_s"] = float(np.mean(times)) if times else None
    if ground_truth is not None:
        out["final_base_speed_mps"] = ground_truth["base_speed"]
        out["final_arm_speed_radps"] = ground_truth["arm_speed"]
        out["final_part_x_m"] = ground_truth["part_x"]
    if perception_errors:
        pe = np.array(perception_errors)
        rms = np.sqrt(np.mean(pe * pe, axis=0))
        out["perception_frames"] = int(len(pe))
        out["perception_rms_xy_mm"], out["perception_rms_z_mm"] = float(rms[0] * 1e3), float(rms[1] * 1e3)
        out["perception_rms_r_deg"] = float(math.degrees(rms[2]))
    if rendered is not None:
        out.update(rendered)
    return out
