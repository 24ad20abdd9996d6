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
* **Width from what is seen.**  One view cannot tell a narrow near column from a wide far one: the
  edge rays of every view (:func:`edge_rays`, kept in the body frame and carried with the odometry
  like the edges) are tangent to the column's circle, ``n_l·(c − o) = −r`` and ``n_r·(c − o) = +r``
  for the left and right rays from the camera position ``o`` (``n`` the ray's left normal) — linear in
  the centre ``c`` and radius ``r`` (:func:`fit_circle`, least squares over the views, with a weak
  prior on ``r`` that decides while the views have no baseline).  Approaching a column ahead (looming)
  or passing it (parallax), two views a few centimetres apart fix both; the remembered edges and the
  width ``2r`` are that fit's, per obstacle (``hierarchy.obstacle_width``, or ``σ z_obstacle``, is only
  the prior).
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
    "Sighting",
    "associate",
    "closing_in",
    "committed_edges",
    "edge_rays",
    "associate_view",
    "circle_edges",
    "edges_in_body",
    "fit_circle",
    "escape_side",
    "has_passed",
    "propagate",
    "remembered_collision",
]


@dataclass(frozen=True)
class Sighting:
    """One view of an obstacle, in the body frame at the obstacle's time: the camera's position ``origin``
    (m, body ``(x, y)``) and the unit directions of its left and right edge rays."""

    origin: Array
    left: Array
    right: Array


@dataclass(frozen=True)
class RememberedObstacle:
    """An obstacle placed in the body frame: its left and right edge points ``p1``, ``p2`` (m, body
    ``(x, y)`` at time ``t``, s), its estimated width ``width`` (m), the committed escape side
    (``LEFT``, ``RIGHT``, or 0 while the task has not activated for it) and the views it was placed from
    (:class:`Sighting`, same frame)."""

    p1: Array
    p2: Array
    width: float
    t: float
    side: int = 0
    sightings: tuple[Sighting, ...] = ()

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


def associate_view(remembered: Sequence[RememberedObstacle], seen: Sighting, tolerance: float) -> int | None:
    """Index of the remembered obstacle the view ``seen`` shows: the one whose centre, seen from the
    camera, lies nearest in bearing to the view's centre bearing, if within its angular half-width plus
    ``tolerance`` (rad) — a bearing test, since one view does not give the distance."""
    mid = seen.left + seen.right
    beta = math.atan2(mid[1], mid[0])
    best, best_d = None, math.inf
    for i, r in enumerate(remembered):
        v = r.centre - seen.origin
        rho = float(np.hypot(*v))
        if rho <= 0.5 * r.width:
            continue
        d = abs(math.remainder(math.atan2(v[1], v[0]) - beta, 2.0 * math.pi))
        if d < math.asin(min(1.0, 0.5 * r.width / rho)) + tolerance and d < best_d:
            best, best_d = i, d
    return best


def circle_edges(centre: ArrayLike, radius: float, origin: ArrayLike) -> tuple[Array, Array]:
    """The left and right edge points (body ``(x, y)``) of a circle of ``radius`` at ``centre`` seen from
    ``origin``: ``radius`` either side of the centre across the line of sight."""
    c = np.asarray(centre, dtype=np.float64).reshape(2)
    v = c - np.asarray(origin, dtype=np.float64).reshape(2)
    u = v / max(float(np.hypot(*v)), 1e-9)
    left = np.array([-u[1], u[0]])
    return c + radius * left, c - radius * left


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


def edge_rays(p1: ArrayLike, p2: ArrayLike, T_body_camera: ArrayLike) -> Sighting:
    """The horizontal edge rays (body frame) of an obstacle whose silhouette edges are ``p1``, ``p2``
    (normalised, left and right): the camera's position and the unit directions of ``(x, 0, 1)``."""
    T = np.asarray(T_body_camera, dtype=np.float64).reshape(4, 4)
    dirs = []
    for p in (p1, p2):
        d = T[:3, :3] @ np.array([float(np.asarray(p, dtype=np.float64).reshape(2)[0]), 0.0, 1.0])
        dirs.append(d[:2] / float(np.hypot(d[0], d[1])))
    return Sighting(T[:2, 3].copy(), dirs[0], dirs[1])


def fit_circle(sightings: Sequence[Sighting], prior_radius: float, prior_weight: float = 0.05) -> tuple[Array, float]:
    """Centre (body ``(x, y)``, m) and radius (m) of the circle every sighting's left and right edge rays
    are tangent to: ``n_l·(c − o) + r = 0`` and ``n_r·(c − o) − r = 0`` (``n = (−d_y, d_x)``: the obstacle
    lies right of its left edge ray and left of its right one), least squares with the prior
    ``prior_weight (r − prior_radius) = 0`` (residuals in metres: the weight is the rays' error over the
    prior's, ~2.5 mm / 5 cm).  A single view gives the prior's radius at the distance its angle says; two
    views with a baseline (looming or parallax) fix the radius.  The radius is clipped to
    ``[prior_radius / 4, 4 prior_radius]``."""
    if not sightings:
        raise ValueError("fit_circle needs at least one sighting")
    if not prior_radius > 0.0:
        raise ValueError(f"prior radius must be > 0, got {prior_radius}")
    A, b = [], []
    for s in sightings:
        for d, sign in ((s.left, 1.0), (s.right, -1.0)):
            n = np.array([-d[1], d[0]])
            A.append([n[0], n[1], sign])
            b.append(float(n @ s.origin))
    A.append([0.0, 0.0, prior_weight])
    b.append(prior_weight * prior_radius)
    sol = np.linalg.lstsq(np.array(A), np.array(b), rcond=None)[0]
    r = float(np.clip(sol[2], 0.25 * prior_radius, 4.0 * prior_radius))
    if r != sol[2]:  # the radius at its bound: the centre that fits the rays best with it
        sol = np.linalg.lstsq(np.array(A)[:-1, :2], np.array(b)[:-1] - np.array(A)[:-1, 2] * r, rcond=None)[0]
    return np.asarray(sol[:2], dtype=np.float64), r


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
    seen = tuple(Sighting(R_back @ (v.origin - shift), R_back @ v.left, R_back @ v.right) for v in obstacle.sightings)
    return RememberedObstacle(R_back @ (obstacle.p1 - shift), R_back @ (obstacle.p2 - shift), obstacle.width, t,
                              obstacle.side, seen)


def has_passed(obstacle: RememberedObstacle, margin: float, keep_out: float = 0.0) -> bool:
    """Whether both edge points are more than ``margin`` (m) behind the body's centre and the centre is
    outside the keep-out disc (farther than ``keep_out``, m): a drone that has slid past a column beside
    it, or backs up toward a keyframe, may still be inside the disc and must keep it in mind."""
    return bool(max(obstacle.p1[0], obstacle.p2[0]) < -margin and float(np.hypot(*obstacle.centre)) > keep_out)


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
