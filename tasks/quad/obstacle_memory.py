"""The obstacle the collision task of visual path following remembers, and the side it escapes by.

Beyond Toro-Arcila et al.: their collision task (§3.1, eqs. 8–9, activated with eq. 20) lives in the
image — it needs both edges of the obstacle in view, and once the obstacle leaves the field of view
its error goes to the reference and ``h_a`` decays.  The camera looks 37.6° to each side, so a
column leaves the image while the drone (0.39 m x 0.52 m rotor tips, the camera 0.17 m ahead of the
centre) is still 0.4–0.6 m short of it, and the visual task then pulls the drone back into it.  With
the obstacle dead ahead, eq. (9)'s yaw term ``−d (x1 + x2)`` vanishes, the task only opposes forward
motion, and nothing moves the drone sideways (a symmetric block).

This module gives the two missing pieces, as pure functions (arrays in, arrays out):

* **Memory.**  While the obstacle is seen whole, its edge points are placed in the body frame
  (:func:`edges_in_body`, at the depth its estimated width gives); once it leaves the view they are
  carried along with the body's odometry (:func:`propagate`) until they are behind the body
  (:func:`has_passed`).  Meanwhile the collision task is eq. (8) seen by a virtual camera at the
  body's centre turned toward the remembered obstacle (:func:`remembered_collision`): its image width
  ``d = W / ρ`` (``W`` the width, ``ρ`` the distance) against the width it has at a keep-out distance,
  and its rate is ``(d/ρ)`` times the approach speed — eq. (9) of a centred obstacle, for which only
  the approach moves the edges apart.  Inside the keep-out disc the task stops the drone from
  approaching it further while it passes (motion around the obstacle lies in its null space); the
  obstacle is watched until it is behind the body.  A new view is matched to a remembered obstacle
  by :func:`associate`; a remembered one switches the task on once the drone would reach its disc
  within the activation time (:func:`closing_in`), so that ``h_a`` (eq. 20) is up when it gets there.
* **Escape side.**  Chosen once per obstacle when the task first activates (:func:`escape_side`: away
  from the obstacle's offset in the image, or a fixed side when it is centred) and kept;
  :func:`committed_edges` moves both edge points so that the obstacle's centre lies at least
  ``offset`` on the other side before eq. (9) is evaluated, so its yaw term turns the drone away
  even from a centred obstacle.

Frames: body FLU (x forward, y left); image points in normalised coordinates (x right).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

LEFT, RIGHT = 1, -1  # escape sides: toward the body's +y (left) or −y (right)

__all__ = [
    "LEFT",
    "RIGHT",
    "ObstacleMemory",
    "RememberedObstacle",
    "associate",
    "closing_in",
    "committed_edges",
    "edges_in_body",
    "escape_side",
    "has_passed",
    "propagate",
    "remembered_collision",
]


@dataclass(frozen=True)
class RememberedObstacle:
    """An obstacle placed in the body frame: its left and right edge points ``p1``, ``p2`` (m, body
    ``(x, y)`` at time ``t``, s), its estimated width ``width`` (m) and the committed escape side
    (``LEFT``, ``RIGHT``, or 0 while the task has not activated for it)."""

    p1: Array
    p2: Array
    width: float
    t: float
    side: int = 0

    @property
    def centre(self) -> Array:
        return 0.5 * (self.p1 + self.p2)


@dataclass
class ObstacleMemory:
    """The obstacles a run remembers (not yet behind the drone), kept across the keyframes of a path."""

    obstacles: list[RememberedObstacle] = field(default_factory=list)


def associate(remembered: Sequence[RememberedObstacle], seen: RememberedObstacle, gate: float) -> int | None:
    """Index of the remembered obstacle whose centre is nearest to ``seen``'s, if within ``gate`` (m)."""
    best, best_d = None, gate
    for i, r in enumerate(remembered):
        dist = float(np.hypot(*(r.centre - seen.centre)))
        if dist < best_d:
            best, best_d = i, dist
    return best


def edges_in_body(p1: ArrayLike, p2: ArrayLike, width: float, T_body_camera: ArrayLike) -> tuple[Array, Array]:
    """Body-frame ``(x, y)`` (m) of the two edges of an obstacle ``width`` metres wide whose silhouette
    edges are ``p1``, ``p2`` (normalised image coordinates; left, right): taken as a cylinder of that
    diameter, its centre lies at ``ρ = (width/2) / sin(α/2)`` along the mean bearing ``β`` of the two
    edge rays (``α`` the angle between them), and the edges ``width/2`` either side of it across the
    line of sight; through ``eT_c`` to the body.  (Facing the camera on the optical axis, ``ρ`` is eq.
    8's ``width / ‖p1 − p2‖``; off the axis the angle, not the normalised width, gives the distance.)"""
    a = np.asarray(p1, dtype=np.float64).reshape(2)
    b = np.asarray(p2, dtype=np.float64).reshape(2)
    b1, b2 = math.atan(a[0]), math.atan(b[0])
    alpha = abs(b2 - b1)
    if not (alpha > 0.0 and width > 0.0):
        raise ValueError(f"need distinct edge points and a positive width, got {a}, {b}, width = {width}")
    beta = 0.5 * (b1 + b2)
    rho = 0.5 * width / math.sin(0.5 * alpha)
    y = 0.5 * (a[1] + b[1]) * rho * math.cos(beta)  # the edges' height in the camera frame
    centre = np.array([rho * math.sin(beta), y, rho * math.cos(beta)])
    across = 0.5 * width * np.array([math.cos(beta), 0.0, -math.sin(beta)])
    T = np.asarray(T_body_camera, dtype=np.float64).reshape(4, 4)
    pts = np.array([centre - across, centre + across]) @ T[:3, :3].T + T[:3, 3]
    return pts[0, :2].copy(), pts[1, :2].copy()


def propagate(obstacle: RememberedObstacle, nu_body: ArrayLike, t: float) -> RememberedObstacle:
    """``obstacle`` at time ``t``: the body moved with ``nu_body = [vx, vy, vz, wz]`` (m/s, rad/s, body
    frame) since ``obstacle.t``, so a fixed point ``P`` becomes ``R(−θ)(P − R(θ/2) v Δt)`` with
    ``θ = wz Δt`` (the constant-twist motion to second order)."""
    nu = np.asarray(nu_body, dtype=np.float64).reshape(4)
    dt = t - obstacle.t
    if dt < 0.0:
        raise ValueError(f"cannot propagate an obstacle seen at t = {obstacle.t} back to t = {t}")
    th = nu[3] * dt
    c, s = math.cos(th / 2.0), math.sin(th / 2.0)
    shift = np.array([c * nu[0] - s * nu[1], s * nu[0] + c * nu[1]]) * dt
    c, s = math.cos(th), math.sin(th)
    R_back = np.array([[c, s], [-s, c]])  # R(−θ)
    return RememberedObstacle(R_back @ (obstacle.p1 - shift), R_back @ (obstacle.p2 - shift), obstacle.width, t,
                              obstacle.side)


def has_passed(obstacle: RememberedObstacle, margin: float) -> bool:
    """Whether both edge points are more than ``margin`` (m) behind the body's centre."""
    return bool(max(obstacle.p1[0], obstacle.p2[0]) < -margin)


def remembered_collision(obstacle: RememberedObstacle, keep_out: float) -> tuple[float, Array]:
    """Eqs. (8)–(9) seen from the body's centre looking at the obstacle: its width ``d = W/ρ`` against
    the width it has at the keep-out distance, ``e_a = W/ρ − W/keep_out`` (eq. 8 with ``σ = W/keep_out``:
    positive inside the keep-out disc), and the 1x6 Jacobian on the **body** twist ``[v; w]``:
    ``(W/ρ²) [ûx, ûy, 0, 0, 0, 0]`` (``ρ``, ``û``: distance and direction of the obstacle's centre;
    approaching it at speed ``û·v`` widens it at ``(d/ρ) û·v``, and turning about the centre does not).
    Multiply by ``Ad_body_camera`` for the camera twist."""
    if not keep_out > 0.0:
        raise ValueError(f"keep-out distance must be > 0, got {keep_out}")
    c = obstacle.centre
    rho = float(np.hypot(*c))
    if rho <= 0.0:
        raise ValueError("the remembered obstacle is at the body's centre")
    d = obstacle.width / rho
    J = np.zeros((1, 6))
    J[0, :2] = (d / rho) * c / rho
    return d - obstacle.width / keep_out, J


def closing_in(obstacle: RememberedObstacle, nu_body: ArrayLike, keep_out: float, horizon: float) -> bool:
    """Whether the body's centre is inside the keep-out disc of ``obstacle`` or will be within
    ``horizon`` seconds at its current approach speed ``max(0, û·v)`` (``nu_body = [vx, vy, vz, wz]``):
    the task's weight (eq. 20) must rise over its activation time before the disc is reached."""
    c = obstacle.centre
    rho = float(np.hypot(*c))
    if rho <= 0.0:
        return True
    v = np.asarray(nu_body, dtype=np.float64).reshape(4)[:2]
    return bool(rho - max(0.0, float(c @ v) / rho) * horizon < keep_out)


def escape_side(p1: ArrayLike, p2: ArrayLike, deadband: float, default: int) -> int:
    """The side to pass an obstacle whose edges are ``p1``, ``p2`` (normalised): away from its centre
    ``c = (x1 + x2)/2`` — ``LEFT`` when it is right of the optical axis (``c > deadband``), ``RIGHT``
    when left of it (``c < −deadband``) — and ``default`` when it is centred within the deadband."""
    if default not in (LEFT, RIGHT):
        raise ValueError(f"default side must be LEFT (1) or RIGHT (-1), got {default}")
    c = 0.5 * (float(np.asarray(p1, dtype=np.float64).reshape(2)[0]) + float(np.asarray(p2, dtype=np.float64).reshape(2)[0]))
    if c > deadband:
        return LEFT
    if c < -deadband:
        return RIGHT
    return default


def committed_edges(p1: ArrayLike, p2: ArrayLike, side: int, offset: float) -> tuple[Array, Array]:
    """The edge points (normalised) shifted sideways together so that the obstacle's centre lies at
    least ``offset`` away from the escape ``side`` (``x ≥ offset`` when escaping ``LEFT``, ``≤ −offset``
    when ``RIGHT``); unchanged when it already does or ``side`` is 0.  Eq. (9) at these points turns the
    camera toward ``side`` when the drone moves forward in the task's null space."""
    a = np.asarray(p1, dtype=np.float64).reshape(2).copy()
    b = np.asarray(p2, dtype=np.float64).reshape(2).copy()
    if side == 0:
        return a, b
    if side not in (LEFT, RIGHT):
        raise ValueError(f"side must be LEFT (1), RIGHT (-1) or 0, got {side}")
    c = 0.5 * (a[0] + b[0])
    target = max(c, offset) if side == LEFT else min(c, -offset)
    a[0] += target - c
    b[0] += target - c
    return a, b
