"""CPU time of the yaw-from-H solve (``homography_yaw``, issue 24) on drone views of a wall.

Run: ``python benchmarks/yaw_solve.py [--cases 200] [--repeats 5]`` — the same file with another checkout's
environment times that checkout's ``homography_yaw`` (same signature before and after issue 24), so running
it alternately in two environments compares them.  Views: a level camera 0–25 cm and up to 20° from its
keyframe, 150 points on a wall 3.2 m ahead, 0.5 px pixel noise (the geometric camera's), H by least
squares.  Prints per repeat the mean CPU time (``time.process_time``) per call, then a JSON line with the
best repeat (the least disturbed by other jobs on a shared machine) and the median.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time

import numpy as np
from taskflow_tasks.quad.homography import euclidean_homography, intrinsic_matrix, normalize_pixels
from taskflow_tasks.quad.yaw_decoupling import homography_yaw

from taskflow.spatial import R_FLU_OPTICAL

YAW_AXIS = np.array([0.0, -1.0, 0.0])  # body z (up) in the optical camera frame
K = intrinsic_matrix(208.0, 208.0, 160.0, 120.0)


def view(x: float, y: float, yaw: float, X: np.ndarray) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ R_FLU_OPTICAL
    Xc = (X - [x, y, 1.0]) @ R
    return (Xc[:, :2] / Xc[:, 2:3]) * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]


def cases(n: int, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    X = np.column_stack((np.full(150, 3.2), rng.uniform(-2.0, 2.0, 150), rng.uniform(0.2, 2.3, 150)))
    kf = view(0.0, 0.0, 0.0, X)
    out = []
    for _ in range(n):
        x, y, yaw = rng.uniform(-0.25, 0.1), rng.uniform(-0.25, 0.25), rng.uniform(-0.35, 0.35)
        cur = view(x, y, yaw, X) + rng.normal(scale=0.5, size=kf.shape)
        out.append((euclidean_homography(cur, kf + rng.normal(scale=0.5, size=kf.shape), K), normalize_pixels(cur, K)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    data = cases(args.cases)
    per_call = []
    for r in range(args.repeats):
        t0 = time.process_time()
        for H, m in data:
            homography_yaw(H, YAW_AXIS, m)
        per_call.append((time.process_time() - t0) / len(data) * 1e6)
        print(f"repeat {r}: {per_call[-1]:.1f} us a call", flush=True)
    print(json.dumps({"benchmark": "yaw_solve", "cases": args.cases, "homography_yaw_us_best": round(min(per_call), 1),
                      "homography_yaw_us_median": round(statistics.median(per_call), 1),
                      "homography_yaw_us": [round(x, 1) for x in per_call]}))


if __name__ == "__main__":
    main()
