"""The collision-avoidance task of the visual-path law (§3.1, eqs. 8–9, activated by eq. 20), on the
obstacle in view or, by default, on the obstacles it remembers in the body frame
(:mod:`taskflow_tasks.quad.obstacle_memory`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray
from taskflow_tasks.quad.gains import HierarchyGains
from taskflow_tasks.quad.hierarchy import Activation, collision_error, collision_jacobian
from taskflow_tasks.quad.homography import normalize_pixels
from taskflow_tasks.quad.obstacle_memory import (
    LEFT,
    RIGHT,
    ObstacleMemory,
    RememberedObstacle,
    Sighting,
    associate,
    associate_view,
    circle_edges,
    closing_in,
    committed_edges,
    edge_rays,
    edges_in_body,
    escape_side,
    fit_circle,
    has_passed,
    propagate,
    remembered_collision,
)
from taskflow_tasks.quad.perception import ObstacleDetection

from taskflow.spatial import transform, vee

Array = NDArray[np.float64]

__all__ = ["CollisionTask"]


class CollisionTask:
    """``(e_a, J_a, h_a)`` of one frame: the error (8), its Jacobian (9) in the camera frame and the
    activation (20), which it keeps with the last ``J_a`` and the obstacle memory."""

    def __init__(self, K: Array, Ad_body_camera: Array, hier: HierarchyGains, t_enter: float,
                 memory: ObstacleMemory | None = None) -> None:
        self.K, self.Ad_body_camera, self.hier = K, Ad_body_camera, hier
        self.J_a_last: Array | None = None
        self.memory = memory if memory is not None else ObstacleMemory()
        self.act_a = Activation(hier.activation_s, t=t_enter)
        R = Ad_body_camera[:3, :3]
        self.T_body_camera = transform(R, vee(Ad_body_camera[:3, 3:] @ R.T))  # eq. (5): [[R, [t]x R], [0, R]]

    def __call__(self, t: float, obstacle: ObstacleDetection | None, nu_body: Array | None) -> tuple[float, Array, float]:
        """The task on this frame's ``obstacle`` (``None``: none whole in view) with the body's measured
        velocity ``nu_body`` (``None``: taken as zero)."""
        hier = self.hier
        if hier.collision and hier.memory:
            e_a, J_a, active_a = self._remembering(t, obstacle, np.zeros(4) if nu_body is None else nu_body)
            return e_a, J_a, self.act_a.update(active_a, t)
        return self._paper(t, obstacle)

    def _paper(self, t: float, obstacle: ObstacleDetection | None) -> tuple[float, Array, float]:
        """Eqs. (8)-(9) on the obstacle in view, ``h_a`` by eq. (20); out of view ``e_a`` is at its
        reference (0) while ``h_a`` decays with the last ``J_a`` (``hierarchy.memory: false``)."""
        hier = self.hier
        e_a, J_a, active_a = 0.0, np.zeros((1, 6)), False
        if obstacle is not None and hier.collision:
            p1n, p2n = normalize_pixels([obstacle.p1, obstacle.p2], self.K)
            e_a = collision_error(p1n, p2n, hier.sigma)
            J_a = collision_jacobian(p1n, p2n, hier.z_obstacle, hier.z_obstacle)
            active_a = e_a > 0.0
            self.J_a_last = J_a
        elif self.J_a_last is not None:
            J_a = self.J_a_last
        h_a = self.act_a.update(active_a, t)
        if (obstacle is None or not hier.collision) and h_a <= 0.0:
            self.J_a_last = None
            J_a = np.zeros((1, 6))
        return e_a, J_a, h_a

    def _remembering(self, t: float, obstacle: ObstacleDetection | None,
                     nu_body: Array) -> tuple[float, Array, bool]:
        """``(e_a, J_a, active)`` with the obstacle memory (:mod:`~taskflow_tasks.quad.obstacle_memory`).

        Every remembered obstacle is carried along with ``nu_body`` and forgotten once behind the body.
        A whole obstacle in view is placed in the body frame and replaces the remembered one it
        matches (centres within ``0.5 m``), keeping that one's escape side, or is added once the task
        activates for it (``e_a > 0``).  The task acts on a remembered obstacle out of view that the
        drone is inside of, or would reach within the activation time, the keep-out disc of
        (:func:`~taskflow_tasks.quad.obstacle_memory.closing_in`; the nearest by
        :func:`~taskflow_tasks.quad.obstacle_memory.remembered_collision` — with the width from the views,
        the one in view counts too while eq. (8) does not yet find it too close), and is then active, so that
        ``h_a`` (eq. 20) is up when the drone gets there; otherwise on the one in view: eq. (8), and
        eq. (9) at the edges moved to the committed escape side (chosen when the task first activates
        for it), active when ``e_a > 0``; otherwise, inactive, on the nearest remembered one.  With
        ``width_from_views`` every view is kept with its remembered obstacle (matched by bearing,
        :func:`~taskflow_tasks.quad.obstacle_memory.associate_view`) and the obstacle's place and width are
        the fit of all of them (:func:`~taskflow_tasks.quad.obstacle_memory.fit_circle`)."""
        hier, mem = self.hier, self.memory
        rems = [propagate(r, nu_body, t) for r in mem.obstacles]
        rems = [r for r in rems if not has_passed(r, hier.pass_margin_m, hier.keep_out_m)]
        seen, view = None, None
        if obstacle is not None:
            p1n, p2n = normalize_pixels([obstacle.p1, obstacle.p2], self.K)
            e_view = collision_error(p1n, p2n, hier.sigma)
            prior = hier.obstacle_width if hier.obstacle_width is not None else hier.sigma * hier.z_obstacle
            if hier.width_from_views:
                rays = edge_rays(p1n, p2n, self.T_body_camera)
                i = associate_view(rems, rays, _BEARING_GATE)
                sightings = _kept(rems[i].sightings if i is not None else (), rays)
                centre, radius = fit_circle(sightings, 0.5 * prior)
                p1, p2 = circle_edges(centre, radius, rays.origin)
                width = 2.0 * radius
            else:
                sightings = ()
                p1, p2 = edges_in_body(p1n, p2n, prior, self.T_body_camera)
                width = prior
                i = associate(rems, RememberedObstacle(p1, p2, width, t), 0.5)
            side = rems[i].side if i is not None else 0
            seen = RememberedObstacle(p1, p2, width, t, side, sightings)
            closing = hier.width_from_views and closing_in(seen, nu_body, hier.keep_out_m, hier.activation_s)
            if side == 0 and (e_view > 0.0 or closing):
                side = escape_side(p1n, p2n, 0.5 * hier.escape_offset, LEFT if hier.escape_side == "left" else RIGHT)
            seen = replace(seen, side=side)
            if i is not None:
                rems[i] = seen
            elif e_view > 0.0 or hier.width_from_views:  # remembered once the task acts on it, or to be fitted
                rems.append(seen)
            c1, c2 = committed_edges(p1n, p2n, side, hier.escape_offset)
            view = (e_view, collision_jacobian(c1, c2, hier.z_obstacle, hier.z_obstacle))
        mem.obstacles = rems
        horizon = hier.activation_s
        # the obstacles out of view, and the one in view while eq. (8) does not yet see it too close
        others = [r for r in rems if r is not seen or (hier.width_from_views and view is not None and view[0] <= 0.0)]
        out_of_view = [(*remembered_collision(r, hier.keep_out_m), closing_in(r, nu_body, hier.keep_out_m, horizon))
                       for r in others]
        nearest = max(out_of_view, key=lambda eja: (eja[2], eja[0])) if out_of_view else None
        if nearest is not None and (nearest[2] or view is None):
            return nearest[0], nearest[1] @ self.Ad_body_camera, nearest[2]
        if view is not None:
            return view[0], view[1], view[0] > 0.0
        return 0.0, np.zeros((1, 6)), False


_BEARING_GATE = 0.05  # rad: a view belongs to a remembered obstacle within its angular half-width plus this
_MAX_SIGHTINGS = 40


def _kept(sightings: tuple[Sighting, ...], new: Sighting) -> tuple[Sighting, ...]:
    """The views a fit uses: the first one (the longest baseline), and the latest ``_MAX_SIGHTINGS`` − 1
    taken at least 1 cm apart."""
    if sightings and float(np.hypot(*(new.origin - sightings[-1].origin))) < 0.01:
        return sightings[:-1] + (new,) if len(sightings) > 1 else sightings
    out = sightings + (new,)
    return out if len(out) <= _MAX_SIGHTINGS else (out[0], *out[-(_MAX_SIGHTINGS - 1):])
