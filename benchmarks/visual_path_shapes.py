"""The taught paths of ``benchmarks/visual_path.py --shapes`` and ``benchmarks/visual_path_obstacles.py``: the
shipped oval, other shapes and a figure-eight, as keyframe poses ``(x, y, yaw)`` built from straight lines and
circular arcs, and :func:`shape_mission`, which writes ``visual_path_oval``'s mission flying one of them."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OVAL = ROOT / "missions" / "visual_path_oval.yaml"


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


def build(*parts: tuple[str, float, float, int]) -> list[tuple[float, float, float]]:
    """Keyframe poses from the start ``(0, 0, 0)`` along ``parts``: ``("line", length, 0, n)`` or
    ``("arc", radius, angle, n)`` (``angle`` rad, + = left), each ending ``n`` keyframes further."""
    pose, out = (0.0, 0.0, 0.0), []
    for kind, a, b, n in parts:
        seg = _straight(*pose, a, n) if kind == "line" else _arc(*pose, a, b, n)
        out += seg
        pose = seg[-1]
    return out


FIGURE_EIGHT_RADIUS, FIGURE_EIGHT_HALF_ANGLE = 0.59, math.radians(30.0)


def figure_eight() -> list[tuple[float, float, float]]:
    """A figure-eight from ``(0, 0, 0)``: a straight leg along +x, a right-hand loop of radius 0.59 m (the
    oval's) turning by ``π + 2·30°``, the second leg crossing the first at 60° in its middle, and a
    left-hand loop back to the start; the legs are ``2 r cos θ / sin θ`` = 2.04 m long (4 keyframes
    0.51 m apart, as the oval's straights), the loops 15 keyframes of 16°: 38 keyframes.  The first leg
    runs along y = 0 from x = 0 to 2.04 m and crosses the second at x = 1.02 m."""
    r, th = FIGURE_EIGHT_RADIUS, FIGURE_EIGHT_HALF_ANGLE
    leg, turn = 2.0 * r * math.cos(th) / math.sin(th), math.pi + 2.0 * th
    return build(("line", leg, 0, 4), ("arc", r, -turn, 15), ("line", leg, 0, 4), ("arc", r, turn, 15))


def climb() -> list[tuple[float, float, float, float]]:
    """A straight 3 m path along +x from ``(0, 0, 1 m)`` with keyframes 0.5 m apart climbing to an apex of
    1.6 m at x = 1.5 m and back down to 1.0 m: poses ``(x, y, z, yaw)``."""
    return [(0.5 * i, 0.0, z, 0.0) for i, z in enumerate((1.2, 1.4, 1.6, 1.4, 1.2, 1.0), start=1)]


def path_shapes() -> dict[str, list[tuple[float, float, float]]]:
    """Taught paths ``(x, y, yaw)`` from the start ``(0, 0, 0)`` inside the oval's room (x in (-1.4, 3.4),
    y in (-0.8, 2.0)), keyframes ~16° and ≤ 0.5 m apart like the shipped oval's:

    * ``oval`` — the shipped one (2 m straights, semicircles of radius 0.59 m, 11 keyframes each);
    * ``oval_tight`` — semicircles of radius 0.45 m (8 keyframes of 22.5° each, 0.18 m apart);
    * ``s_bend`` — 1 m straight, a left and a right quarter circle of radius 0.6 m (6 keyframes each), 0.5 m;
    * ``rounded_rectangle`` — 1.5 m and 0.6 m sides joined by quarter circles of radius 0.4 m, closed.
    """

    half = math.pi
    return {
        "oval": build(("line", 2.0, 0, 4), ("arc", 0.59, half, 11), ("line", 2.0, 0, 4), ("arc", 0.59, half, 11)),
        "oval_tight": build(("line", 2.0, 0, 4), ("arc", 0.45, half, 8), ("line", 2.0, 0, 4), ("arc", 0.45, half, 8)),
        "s_bend": build(("line", 1.0, 0, 2), ("arc", 0.6, half / 2, 6), ("arc", 0.6, -half / 2, 6), ("line", 0.5, 0, 1)),
        "rounded_rectangle": build(("line", 1.5, 0, 3), ("arc", 0.4, half / 2, 5), ("line", 0.6, 0, 2),
                                   ("arc", 0.4, half / 2, 5), ("line", 1.5, 0, 3), ("arc", 0.4, half / 2, 5),
                                   ("line", 0.6, 0, 2), ("arc", 0.4, half / 2, 5)),
    }


def shape_mission(name: str, poses: Sequence[tuple[float, float, float]] | Sequence[tuple[float, float, float, float]],
                  out: Path, room_margin: float | None = 1.6, heights: Sequence[float] | None = None) -> Path:
    """``visual_path_oval``'s mission (no feed-forward, yaw from H) flying ``poses`` (``(x, y, yaw)`` at 1 m,
    or ``(x, y, z, yaw)``), written to ``out/visual_path_NAME.yaml``: its keyframes and path replaced and,
    unless ``room_margin`` is None, a room ``room_margin`` metres beyond the path every way (the geometric
    camera's 20 landmarks per m² of a wall faced closer than ~1.2 m across a 22° keyframe step leave fewer
    than 16 shared points).  Returns the file."""
    text = OVAL.read_text()
    head, rest = text.split("    keyframes:\n", 1)
    tail = rest[rest.index("rate_hz:"):]  # the keyframe list ends where the mission's top-level keys resume
    full = [(q[0], q[1], 1.0, q[2]) if len(q) == 3 else tuple(q) for q in poses]
    kfs = [f"      - {{id: {i}, pose: [{x:.4f}, {y:.4f}, {z:.4f}, {math.remainder(yaw, 2 * math.pi):.4f}]}}\n"
           for i, (x, y, z, yaw) in enumerate(full)]
    top = head.replace("mission: visual_path_oval", f"mission: visual_path_{name}", 1)
    if room_margin is not None:
        xs, ys = [q[0] for q in full], [q[1] for q in full]
        room = (f"{{x0: {min(xs) - room_margin:.2f}, x1: {max(xs) + room_margin:.2f}, y0: {min(ys) - room_margin:.2f}, "
                f"y1: {max(ys) + room_margin:.2f}, height: 2.5}}")
        top = re.sub(r"    room: \{[^}]*\}", f"    room: {room}", top, count=1)
    out.mkdir(parents=True, exist_ok=True)
    file = out / f"visual_path_{name}.yaml"
    ids = ", ".join(f"{{id: {i}}}" for i in range(len(full)))
    file.write_text(top + "    keyframes:\n" + "".join(kfs) + re.sub(r"  path: \[[^\]]*\]", f"  path: [{ids}]", tail, count=1))
    return file


COLUMNS_HIERARCHY = "{sigma: 0.25, lambda_a: 0.01, lambda_m: 0.2, activation_s: 0.5, visibility: false}"
BLOCKED_RULE = ('            - {to: blocked, when: "h_a > 0.9 and epsilon_progress < 0.3 px and last_keyframe < 0.5", '
                'for: 1 s}\n')


def with_columns(file: Path) -> Path:
    """The mission of :func:`shape_mission` with the collision task on (obstacle memory, width from the
    views, σ = 0.25, activation 0.5 s, no visibility task as in the oval) and a rule that passes an
    intermediate keyframe an obstacle holds the drone off (``h_a > 0.9`` with ε not falling by 0.3 px a
    second, for 1 s: a column beside the line can stand where the drone would be at the taught pose);
    written next to it as ``…_columns.yaml``."""
    text = file.read_text()
    text = text.replace("    none: {collision: false, visibility: false}", f"    none: {{collision: false, visibility: false}}\n"
                        f"    columns: {COLUMNS_HIERARCHY}", 1)
    text = text.replace("hierarchy: none}", "hierarchy: columns}", 1)
    rule = '            - {to: reached, when: "epsilon_margin < 0 px and last_keyframe < 0.5"}\n'
    text = text.replace(rule, rule + BLOCKED_RULE, 1)
    text = text.replace("        reached: {final: succeeded}\n", "        reached: {final: succeeded}\n"
                        "        blocked: {final: succeeded, description: \"an obstacle holds the drone off this keyframe\"}\n", 1)
    out = file.with_name(file.stem + "_columns.yaml")
    out.write_text(text)
    return out
