"""The screw_conveyor world's part is described by its ``bolts`` layout (built, scored and drawn from that
one parameter), and its camera's noise and dropout act in the rendered (ArUco) mode as in the pose mode."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pybullet as p
import pytest
import taskflow_robots.mobile_iiwa  # noqa: F401 - registers mobile_iiwa
import taskflow_tasks.screw.mobile_pbvs  # noqa: F401 - registers the pbvs tasks
from pydantic import ValidationError
from taskflow_robots.mobile_iiwa import CameraParams, MobileIiwa
from taskflow_sim.screw import scene as sc
from taskflow_sim.screw.world import ScrewConveyor

from taskflow.errors import MissionError
from taskflow.mission.loader import load_mission
from taskflow.testing import assert_outcome, run_on_world

CONVEYOR = Path(__file__).resolve().parents[2] / "missions" / "screw_fastening.yaml"
HOLD = {"base_twist": np.zeros(3), "arm_dq": np.zeros(7)}
TWO_BOLTS = ((0.06, 0.08), (0.10, -0.07))  # in P; the default four are at x 0.02 / 0.12, y ±0.06


def _screws_in_marker(bolts: tuple[tuple[float, float], ...]) -> str:
    """The mission's ``screws`` for ``bolts``, written by hand: marker at (−0.12, 0, 0.0005) in P, head top 8 mm up."""
    return "[" + ", ".join(f"{{xyz: [{x + 0.12:.4f}, {y:.4f}, 0.0075], rpy_deg: [180, 0, -90]}}" for x, y in bolts) + "]"


@pytest.mark.parametrize("bolts, words", [
    ([], "at least one bolt"),
    ([[0.195, 0.0]], "not on the part's top face"),
    ([[0.0, -0.115]], "not on the part's top face"),
    ([[0.0, 0.0], [0.01, 0.01]], "bolts 0 and 1 are 14.1 mm apart"),
    ([[0.02, 0.06], [-0.06, 0.05]], "bolt 1 at (-0.06, 0.05) m covers the ArUco marker"),
])
def test_an_invalid_bolt_layout_is_refused_at_load_with_what_is_wrong(bolts, words):
    with pytest.raises(ValidationError, match=re.escape(words)):
        ScrewConveyor.Params(bolts=bolts)
    override = f"world.params.bolts={bolts}"
    with pytest.raises(MissionError) as exc:
        load_mission(CONVEYOR, [override])
    assert str(exc.value.first).startswith(f"{CONVEYOR}: --set {override}: ") and words in str(exc.value)


def test_the_part_is_built_scored_and_drawn_from_the_layout():
    params = ScrewConveyor.Params(bolts=TWO_BOLTS, part_start=(-0.5, 0.2, 0.3), speed=0.0)
    w = ScrewConveyor(MobileIiwa(MobileIiwa.Params()), params, seed=0)
    w.reset()
    try:
        # the PyBullet body: the box and one head per bolt, at the layout's positions (P = the body's frame)
        shapes = p.getCollisionShapeData(w.part.part, -1, physicsClientId=w.client)
        heads = [s for s in shapes if s[2] == p.GEOM_CYLINDER]
        assert len(shapes) == 3 and len(heads) == 2
        assert sorted((round(s[5][0], 6), round(s[5][1], 6)) for s in heads) == sorted(TWO_BOLTS)
        # scoring: the bolt frames the world measures the tool against
        P = w.part_pose()
        for H, (x, y) in zip(w.bolt_poses(), TWO_BOLTS, strict=True):
            assert H[:3, 3] == pytest.approx(P[:3, :3] @ [x, y, sc.BOLT_HEIGHT] + P[:3, 3], abs=1e-12)
        assert w.summary_metrics()["bolts_on_part"] == 2
        # the scene: the part and its two bolts where the part starts
        markers = ScrewConveyor.scene(params)
        bolts = [m for m in markers if m.label.startswith("bolt")]
        assert [m.label for m in bolts] == ["bolt 0", "bolt 1"] and all(m.radius == sc.BOLT_RADIUS for m in bolts)
        c, s = math.cos(0.3), math.sin(0.3)
        for m, (x, y) in zip(bolts, TWO_BOLTS, strict=True):
            assert m.points[0] == pytest.approx((-0.5 + c * x - s * y, 0.2 + s * x + c * y))
    finally:
        w.close()


def test_a_mission_fastens_the_bolts_of_the_layout_it_is_given():
    """Two bolts elsewhere on the part and the mission's two operation poses on them: both are fastened
    at those bolts (the ground-truth error to each is sub-millimetric to millimetric); the default four
    are not on the part (with them the same poses would find no bolt under the tool)."""
    m = load_mission(CONVEYOR, [f"world.params.bolts={[list(b) for b in TWO_BOLTS]}",
                                f"parameters.screws={_screws_in_marker(TWO_BOLTS)}"])
    r = run_on_world(m, seed=0)
    assert_outcome(r, "succeeded")
    metrics = r.summary["metrics"]
    assert (metrics["bolts_on_part"], metrics["bolts_fastened"], metrics["operations_fastened"]) == (2, 2, 2)
    log = metrics["operation_log"]
    assert [(op["bolt"], op["nearest_bolt"], op["outcome"]) for op in log] == [(0, 0, "fastened"), (1, 1, "fastened")]
    assert all(op["nearest_bolt_mm"] < 3.0 and op["err_t_max_mm"] < 3.0 for op in log)
    # the poses are far from every bolt of the default layout: a world still using it would find none
    nearest_default = min(math.dist(b, d) for b in TWO_BOLTS for d in sc.BOLTS_XY)
    assert nearest_default > 0.02


# -- the rendered camera: noise and dropout ----------------------------------------------------------------

SMALL_CAMERA = MobileIiwa(MobileIiwa.Params(camera=CameraParams(width=480, height=360, rate_hz=20.0)))


def _rendered(seed: int, seconds: float, **params) -> tuple[list[tuple[int, bytes]], dict]:
    """The marker detections the robot received over ``seconds`` of a still scene, in the rendered mode."""
    w = ScrewConveyor(SMALL_CAMERA, ScrewConveyor.Params(perception="rendered", speed=0.0, roi_px=160, **params), seed=seed)
    w.reset()
    received: list[tuple[int, bytes]] = []
    try:
        for _ in range(round(seconds / 0.01)):
            marker = w.observe().sensors["marker"]
            if marker is not None and (not received or marker.seq != received[-1][0]):
                received.append((marker.seq, marker.T_camera_object.tobytes()))
            w.apply(HOLD)
            w.advance(0.01)
        return received, w.summary_metrics()
    finally:
        w.close()


def test_rendered_detections_carry_the_seeded_camera_noise():
    """Nothing moves, so without noise every frame renders the same image; with the camera's pixel noise
    two seeds give different poses frame by frame, and one seed gives the same bytes again."""
    a, _ = _rendered(0, 0.6, dropout=0.0)
    again, _ = _rendered(0, 0.6, dropout=0.0)
    b, _ = _rendered(1, 0.6, dropout=0.0)
    assert len(a) >= 10 and a == again
    assert len(b) == len(a) and sum(x != y for x, y in zip(a, b, strict=True)) >= len(a) - 1
    assert len({pose for _, pose in a}) == len(a)  # the noise is temporal: every frame differs
    quiet, _ = _rendered(0, 0.3, dropout=0.0, image_noise=0.0)
    assert len({pose for _, pose in quiet[1:]}) == 1  # the noiseless camera: one image, one pose


def test_rendered_dropout_misses_about_the_given_fraction_of_frames():
    _, s = _rendered(3, 2.0, dropout=0.5)
    n = s["rendered_frames"] + s["rendered_dropped"]
    assert n == 41  # 20 Hz over 2 s, both ends
    assert abs(s["rendered_dropped"] - 0.5 * n) <= 3.5 * math.sqrt(0.25 * n)  # binomial, 3.5 sigma
    assert s["perception_frames"] == s["rendered_frames"]  # every frame not dropped found the marker


SIX_BOLTS = ((0.02, 0.06), (0.02, -0.06), (0.12, 0.06), (0.12, -0.06), (0.17, 0.0), (0.07, 0.0))


def test_a_mission_listing_fewer_operation_poses_than_the_part_has_bolts_is_refused_at_load():
    """The part's `bolts` (world) and the mission's `screws` were kept in step by hand: a six-bolt part with the
    four shipped poses validated and ended `succeeded` with two bolts unfastened.  The world checks them at load,
    at the --set that changed the layout, and says the poses to write; the matching six load."""
    override = f"world.params.bolts={[list(b) for b in SIX_BOLTS]}"
    with pytest.raises(MissionError) as exc:
        load_mission(CONVEYOR, [override])
    [problem] = exc.value.problems
    assert str(problem).startswith(f"{CONVEYOR}: --set {override}: ")
    assert "`screws` lists 4 operation poses but the part of world 'screw_conveyor' has 6 bolts" in problem.message
    assert "2 of them unfastened" in problem.message
    assert "{xyz: [0.2900, 0.0000, 0.0075], rpy_deg: [180, 0, -90]}" in problem.hint  # bolt 4 in the marker frame
    mission = load_mission(CONVEYOR, [override, f"parameters.screws={_screws_in_marker(SIX_BOLTS)}"])
    assert len(mission.spec.parameters["screws"]) == 6
    # the poses the hint lists are the ones the world scores the tool against
    heads = [T[:3, 3] for T in sc.T_marker_bolts(SIX_BOLTS)]
    assert np.allclose(heads[4], [0.29, 0.0, 0.0075])
