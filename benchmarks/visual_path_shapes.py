"""The taught paths of ``benchmarks/visual_path.py --shapes``: the shipped oval and three other shapes, as
keyframe poses ``(x, y, yaw)``, built from straight lines and circular arcs."""

from __future__ import annotations

import math


def _arc(x: float, y: float, yaw: float, radius: float, angle: float, n: int) -> list[tuple[float, float, float]]:
    """``n`` poses along a circular arc of ``radius`` turning by ``angle`` (rad, + = left) from ``(x, y, yaw)``."""
    cx, cy = x - math.copysign(radius, angle) * math.sin(yaw), y + math.copysign(radius, angle) * math.cos(yaw)
    out = []
    for i in range(1, n + 1):
        a = yaw + angle * i / n
        out.append((cx + math.copysign(radius, angle) * math.sin(a), cy - math.copysign(radius, angle) * math.cos(a), a))
    return out


def _straight(x: float, y: float, yaw: float, length: float, n: int) -> list[tuple[float, float, float]]:
    return [(x + length * i / n * math.cos(yaw), y + length * i / n * math.sin(yaw), yaw) for i in range(1, n + 1)]


def path_shapes() -> dict[str, list[tuple[float, float, float]]]:
    """Taught paths ``(x, y, yaw)`` from the start ``(0, 0, 0)`` inside the oval's room (x in (-1.4, 3.4),
    y in (-0.8, 2.0)), keyframes ~16° and ≤ 0.5 m apart like the shipped oval's:

    * ``oval`` — the shipped one (2 m straights, semicircles of radius 0.59 m, 11 keyframes each);
    * ``oval_tight`` — semicircles of radius 0.45 m (8 keyframes of 22.5° each, 0.18 m apart);
    * ``s_bend`` — 1 m straight, a left and a right quarter circle of radius 0.6 m (6 keyframes each), 0.5 m;
    * ``rounded_rectangle`` — 1.5 m and 0.6 m sides joined by quarter circles of radius 0.4 m, closed.
    """

    def build(*parts: tuple[str, float, float, int]) -> list[tuple[float, float, float]]:
        pose, out = (0.0, 0.0, 0.0), []
        for kind, a, b, n in parts:
            seg = _straight(*pose, a, n) if kind == "line" else _arc(*pose, a, b, n)
            out += seg
            pose = seg[-1]
        return out

    half = math.pi
    return {
        "oval": build(("line", 2.0, 0, 4), ("arc", 0.59, half, 11), ("line", 2.0, 0, 4), ("arc", 0.59, half, 11)),
        "oval_tight": build(("line", 2.0, 0, 4), ("arc", 0.45, half, 8), ("line", 2.0, 0, 4), ("arc", 0.45, half, 8)),
        "s_bend": build(("line", 1.0, 0, 2), ("arc", 0.6, half / 2, 6), ("arc", 0.6, -half / 2, 6), ("line", 0.5, 0, 1)),
        "rounded_rectangle": build(("line", 1.5, 0, 3), ("arc", 0.4, half / 2, 5), ("line", 0.6, 0, 2),
                                   ("arc", 0.4, half / 2, 5), ("line", 1.5, 0, 3), ("arc", 0.4, half / 2, 5),
                                   ("line", 0.6, 0, 2), ("arc", 0.4, half / 2, 5)),
    }
