"""Parameter bounds: every parameter of every robot and world has the range its robot or world can honour,
with the reason in its description (what ``taskflow describe`` shows); values outside it — the physically
meaningless ones of issue 20 — are refused at load with one ``FILE:LINE:COL`` line (or naming the ``--set``)
that gives the reason; the control rate is checked against what the world can honour."""

from __future__ import annotations

import types
import typing
from pathlib import Path

import annotated_types as at
import pytest
import taskflow_missions
from pydantic import BaseModel

from taskflow.catalogue.catalogue import build
from taskflow.catalogue.catalogue_render import describe_text
from taskflow.errors import MissionError
from taskflow.mission.diagnostics import _inner_model
from taskflow.mission.loader import load_mission
from taskflow.registry import ROBOTS, WORLDS

MISSIONS = Path(taskflow_missions.__file__).resolve().parent

# numbers bounded by a model validator against the rest of the model instead of a fixed range, and why
BOUNDED_BY_A_VALIDATOR = {
    "RoomSpec.x0": "the room's walls: x1 - x0 and y1 - y0 between 1 and 100 m",
    "RoomSpec.x1": "as x0", "RoomSpec.y0": "as x0", "RoomSpec.y1": "as x0",
    "ObstacleSpec.x": "a position in the world frame", "ObstacleSpec.y": "as x",
    "KeyframeSpec.id": "0, 1, 2, ... in order (QuadRoomParams._ids)",
    "QuadRoomParams.texture_seed": "any seed",
    "LidarMount.min_range": "below max_range (LidarMount._ranges)",
}


def _fields(model: type[BaseModel], seen: set[type]) -> typing.Iterator[tuple[type[BaseModel], str, typing.Any]]:
    for name, info in model.model_fields.items():
        inner = _inner_model(info.annotation)
        if inner is not None:
            if inner not in seen:
                seen.add(inner)
                yield from _fields(inner, seen)
            if info.description or model in (BaseModel,):
                continue
        yield model, name, info


def _all_fields() -> list[tuple[str, str, typing.Any]]:
    out = []
    for reg in (ROBOTS, WORLDS):
        for name in reg.names():
            if not reg.get(name).__module__.startswith(("taskflow_robots.", "taskflow_sim.")):
                continue  # the tests' own toys
            seen: set[type] = set()
            out += [(name, f"{m.__name__}.{f}", info) for m, f, info in _fields(reg.get(name).Params, seen)]
    return out


@pytest.mark.parametrize("component, field, info", [pytest.param(*t, id=f"{t[0]}:{t[1]}") for t in _all_fields()])
def test_every_parameter_has_bounds_and_says_why(component: str, field: str, info: typing.Any) -> None:
    assert info.description, f"{component} {field}: no description (say what it holds and what bounds it)"
    scalar = info.annotation in (float, int) or (typing.get_origin(info.annotation) in (typing.Union, types.UnionType)
                                                 and set(typing.get_args(info.annotation)) & {float, int})
    if not scalar or field in BOUNDED_BY_A_VALIDATOR:  # tuples (poses, sizes) are checked by their models' validators
        return
    low = any(isinstance(m, (at.Gt, at.Ge)) for m in info.metadata)
    high = any(isinstance(m, (at.Lt, at.Le)) for m in info.metadata)
    assert low and high, f"{component} {field}: a number needs a lower and an upper bound (low={low}, high={high})"


# issue 20's physically meaningless values, and a few more of the same kind: mission, --set, what the line says
MEANINGLESS = [
    ("viki_hyco", "world.params.depth_noise=100", "less than or equal to 0.2", "10 times the RealSense's 2 %"),
    ("viki_hyco", "world.params.pixel_noise=1e6", "less than or equal to 20", "a third of the ~60 px box"),
    ("car_waypoints", "robot.params.wheelbase=1e-6", "greater than or equal to 0.1", "belief of the body's 0.325 m"),
    ("viki_hyco", "world.params.camera_rate_hz=1e-6", "greater than or equal to 1", "act on one frame for 20 ticks"),
    ("car_waypoints", "robot.params.v_max=1000", "less than or equal to 2.5", "the tyres slide"),
    ("viki_hyco", "world.params.object_distance=1e6", "less than or equal to 10", "depth camera's range"),
    ("viki_hyco", "world.params.dropout_burst=1e12", "less than or equal to 150", "the object gone"),
    ("visual_path_oval", "robot.params.v_max=1e-6", "greater than or equal to 0.05", "the saturation, not the visual-servo"),
    ("screw_fastening", "world.params.latency=10", "less than or equal to 0.2", "kp tau < pi/2"),
    ("husky_waypoints", "robot.params.v_max=3", "less than or equal to 1", "the Husky's top speed"),
    ("visual_path_oval", "world.params.frame_latency_s=5", "less than or equal to 0.5", "lambda tau < pi/2"),
    ("screw_fastening", "robot.params.tool.tol_t=0.5", "less than or equal to 0.02", "the next bolt"),
    ("car_waypoints", "robot.params.front_camera.rate_hz=1000", "less than or equal to 90", "RealSense D435i"),
]


@pytest.mark.parametrize("mission, override, message, reason", MEANINGLESS)
def test_a_meaningless_value_is_refused_with_its_reason(mission: str, override: str, message: str, reason: str) -> None:
    with pytest.raises(MissionError) as exc:
        load_mission(MISSIONS / f"{mission}.yaml", [override])
    (p,) = exc.value.problems
    line = str(p)
    assert "\n" not in line and f"--set {override}" in line and message in line and reason in line, line


def test_cross_parameter_bounds() -> None:
    with pytest.raises(MissionError, match="command_delay_s \\+ frame_latency_s = 0.6 s"):
        load_mission(MISSIONS / "visual_path_oval.yaml", ["world.params.frame_latency_s=0.3",
                                                          "world.params.command_delay_s=0.3"])
    with pytest.raises(MissionError, match="beyond the depth camera's range depth_max"):
        load_mission(MISSIONS / "viki_hyco.yaml", ["world.params.object_distance=4", "world.params.depth_max=3"])
    with pytest.raises(MissionError, match="latency \\+ base_delay = 0.8 s"):
        load_mission(MISSIONS / "screw_fastening.yaml", ["world.params.latency=0.2", "world.params.base_delay=0.6"])
    with pytest.raises(MissionError, match="off the floor"):
        load_mission(MISSIONS / "car_waypoints.yaml", ["world.params.start=[30, 0, 0]"])
    with pytest.raises(MissionError, match="beyond the LBR iiwa's ±120 deg limit"):
        load_mission(MISSIONS / "screw_fastening.yaml", ["robot.params.q_home=[0, 2.5, 0, -1.74, 0, 1.75, 0]"])


def test_the_screw_world_refuses_a_control_rate_it_cannot_honour() -> None:
    with pytest.raises(MissionError) as exc:
        load_mission(MISSIONS / "screw_fastening.yaml", ["rate_hz=1"])
    line = str(exc.value.problems[0])
    assert "--set rate_hz=1: control rate_hz 1 Hz is too slow for world 'screw_conveyor'" in line
    assert "moves 50 mm between two commands, more than the tool's coupling tolerance tol_t = 3 mm" in line
    with pytest.raises(MissionError, match="rate_hz 20 Hz is too slow .* moves 4 mm"):  # the trolley fluctuates
        load_mission(MISSIONS / "screw_fastening_trolley.yaml", ["rate_hz=20"])
    # the missions' 100 Hz, the paper's 40 Hz (with a physics rate it divides) and a faster part at 100 Hz stay valid
    assert load_mission(MISSIONS / "screw_fastening.yaml").spec.rate_hz == 100
    assert load_mission(MISSIONS / "screw_fastening.yaml", ["rate_hz=40", "world.params.physics_hz=200"]).spec.rate_hz == 40
    load_mission(MISSIONS / "screw_fastening.yaml", ["world.params.speed=0.08"])
    with pytest.raises(MissionError, match="at least 26.7 Hz"):
        load_mission(MISSIONS / "screw_fastening.yaml", ["world.params.speed=0.08", "rate_hz=25"])


def test_viki_ground_refuses_a_camera_faster_than_the_control_rate() -> None:
    with pytest.raises(MissionError) as exc:
        load_mission(MISSIONS / "viki_hyco.yaml", ["world.params.camera_rate_hz=60"])
    line = str(exc.value.problems[0])
    assert line.startswith(f"{MISSIONS / 'viki_hyco.yaml'}: --set world.params.camera_rate_hz=60: camera rate above "
                           "the control rate_hz 20 Hz (front_camera 60 Hz, rear_camera 60 Hz)"), line
    assert "so the camera would run at 20 Hz" in line
    with pytest.raises(MissionError, match="front_camera 30 Hz"):  # a mount's own rate, on the Husky
        load_mission(MISSIONS / "husky_viki_approach.yaml", ["robot.params.front_camera.rate_hz=30"])
    load_mission(MISSIONS / "viki_hyco.yaml", ["world.params.camera_rate_hz=60", "rate_hz=60"])
    load_mission(MISSIONS / "viki_hyco.yaml", ["world.params.fidelity=paper"])  # 15 fps under 20 Hz


@pytest.mark.parametrize("name, lines", [
    ("racecar", ["v_max: float, default 0.5, unit m/s, > 0, ≤ 2.5 — speed limit (m/s; paper: 0.5): at most 2.5 m/s",
                 "wheelbase: float, default 0.325, unit m, ≥ 0.1, ≤ 1 — m: the controller's belief"]),
    ("viki_ground", ["pixel_noise: float, default 0.5, unit px, ≥ 0, ≤ 20 — std of each box edge (px)",
                     "dropout_burst: float, default 1.0, ≥ 1, ≤ 150 — mean length of a miss burst"]),
    ("car_goto", ["pos_error: m, ≥ 0 (a distance)"]),
])
def test_describe_shows_the_bounds_and_their_reason(name: str, lines: list[str]) -> None:
    text = describe_text(build().find(name))
    for line in lines:
        assert any(line in t for t in text.splitlines()), (line, text)
