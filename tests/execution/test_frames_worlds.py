"""The rendered ViKi and screw worlds publish the image their detector got (``sensors.image``), so their
rendered runs record camera frames (taskflow/execution/frames.py) at the declared rate, with no extra rendering."""

from __future__ import annotations

from pathlib import Path

import cv2

from taskflow.execution.frames import read_frames
from taskflow.execution.runtime import run_mission
from taskflow.messages import Image
from taskflow.mission.loader import load_mission

MISSIONS = Path(__file__).resolve().parents[2] / "missions"


def _frames_run(mission: str, overrides: list[str], out: Path) -> list:
    m = load_mission(MISSIONS / mission, overrides)
    assert m.world_cls.observations["sensors.image"].cls is Image  # declared: the contract and catalogue know it
    result = run_mission(m, seed=0, max_time=2.0, out_dir=out, frames_hz=2)
    assert result.outcome == "timeout"
    frames = read_frames(out)
    for f in frames:
        px = cv2.imread(str(out / f.file), cv2.IMREAD_UNCHANGED)
        assert (px.shape[1], px.shape[0]) == (f.width, f.height) and px.std() > 1.0  # a rendered scene
        assert f.stamp == f.t  # captured on the tick that recorded it (camera frames fall on these ticks)
    return frames


def test_viki_rendered_run_records_the_active_cameras_frames(tmp_path: Path) -> None:
    frames = _frames_run("viki_hyco.yaml", ["world.params.perception=rendered", "world.params.image_size=[64, 48]"],
                         tmp_path / "run")
    # 20 Hz control, the front camera (15 Hz) has a frame at the first tick: due at 0, 0.5, 1, 1.5 s
    assert [f.tick for f in frames] == [0, 10, 20, 30]
    assert {(f.sensor, f.frame, f.width, f.height) for f in frames} == {("image", "front_camera", 64, 48)}


def test_screw_rendered_run_records_the_detectors_frames(tmp_path: Path) -> None:
    frames = _frames_run("screw_fastening.yaml", ["world.params.perception=rendered", "world.params.roi_px=64",
                                                  "robot.params.camera.width=160", "robot.params.camera.height=120"],
                         tmp_path / "run")
    # 100 Hz control; no image before the camera's first frame (taken during the first step), so the one
    # due at 0 s finds none and the next is at 0.5 s
    assert [f.tick for f in frames] == [50, 100, 150]
    assert {f.frame for f in frames} == {"camera"}
    # the marker is too small to find at 160x120: every frame is the coarse search view (a quarter, grey)
    assert {(f.width, f.height) for f in frames} == {(40, 30)}
    assert cv2.imread(str(tmp_path / "run" / frames[0].file), cv2.IMREAD_UNCHANGED).ndim == 2
