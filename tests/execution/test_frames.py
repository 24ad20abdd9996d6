"""Camera frames in the run record (taskflow/execution/frames.py): recorded at the declared rate on simulation time,
byte for byte again with the same seed, kept when a run fails, served by the view and exported to MCAP."""

from __future__ import annotations

import base64
import json
import urllib.error
import urllib.request
from pathlib import Path

import cv2
import numpy as np
import pytest
from conftest import rendered_run

from taskflow.api import Observation
from taskflow.cli import main
from taskflow.execution.frames import DEFAULT_HZ, FrameRecorder, nearest, read_frames
from taskflow.messages import Image
from taskflow.mission.loader import load_mission
from taskflow.operate.replay import serve_replay
from taskflow.readers.telemetry import export_run
from taskflow.testing import Script, ScriptedWorld, drive

HERE = Path(__file__).resolve().parents[1]
TOY = HERE / "machine" / "missions" / "toy_full.yaml"
RATE = 25.0  # the rendered mission's control rate (and the quadcopter camera's)


def _image(t: float, value: int = 0, shape: tuple[int, ...] = (6, 8, 3)) -> Image:
    return Image(stamp=t, frame="camera", pixels=np.full(shape, value, dtype=np.uint8))


# -- the recorder on its own ------------------------------------------------------------------------------


def test_frames_are_due_on_simulation_time_and_an_image_is_written_once(tmp_path: Path) -> None:
    rec = FrameRecorder(tmp_path, hz=4.0)
    dt = 0.1
    for k in range(11):  # 0 .. 1.0 s at 10 Hz; the camera at 5 Hz (its image changes every other tick)
        t = k * dt
        cam = 2 * dt * (k // 2)
        rec.offer(t, k, {"image": _image(cam, k), "keyframes": (_image(0.0),), "frame_id": k})
    frames = read_frames(tmp_path)  # before close: each line is flushed with its frame
    # due at 0, .25, .5, .75, 1.0: taken by the first tick at or after; at 0.3 the image is still 0.2's
    assert [(f.tick, f.stamp) for f in frames] == [(0, 0.0), (3, 0.2), (5, 0.4), (8, 0.8), (10, 1.0)]
    assert {f.sensor for f in frames} == {"image"}  # the keyframe tuple is input, not what the camera saw
    px = cv2.imread(str(tmp_path / frames[1].file), cv2.IMREAD_UNCHANGED)
    assert px.shape == (6, 8, 3) and (px == 3).all()
    rec.close()


def test_grey_images_and_colours_survive_the_file(tmp_path: Path) -> None:
    rgb = np.zeros((4, 5, 3), dtype=np.uint8)
    rgb[..., 0] = 200  # red
    rec = FrameRecorder(tmp_path, hz=1.0)
    rec.offer(0.0, 0, {"a": Image(stamp=0.0, frame="c", pixels=rgb), "b": _image(0.0, 77, (4, 5))})
    rec.close()
    a, b = read_frames(tmp_path)
    bgr = cv2.imread(str(tmp_path / a.file), cv2.IMREAD_UNCHANGED)
    assert (bgr[..., 2] == 200).all() and (bgr[..., :2] == 0).all()
    grey = cv2.imread(str(tmp_path / b.file), cv2.IMREAD_UNCHANGED)
    assert grey.shape == (4, 5) and (grey == 77).all() and (b.width, b.height) == (5, 4)


def test_nearest_picks_by_capture_time_and_the_latest_without_a_time(tmp_path: Path) -> None:
    rec = FrameRecorder(tmp_path, hz=2.0)
    for k in range(5):
        rec.offer(0.5 * k, k, {"image": _image(0.5 * k)})
    frames = read_frames(tmp_path)
    assert nearest(frames, "image", 0.74).stamp == 0.5
    assert nearest(frames, "image", 0.76).stamp == 1.0
    assert nearest(frames, "image", None).stamp == 2.0
    assert nearest(frames, "depth", 1.0) is None


@pytest.mark.parametrize("hz", [0.0, -1.0, float("nan")])
def test_a_bad_rate_is_refused_with_the_valid_range(tmp_path: Path, hz: float) -> None:
    with pytest.raises(ValueError, match="positive number"):
        FrameRecorder(tmp_path, hz)


def test_run_frames_option_rejects_a_negative_rate_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(TOY), "--frames", "-2", "--no-control"]) == 1
    err = capsys.readouterr().err
    assert "--frames '-2'" in err and ">= 0" in err and "Traceback" not in err


# -- in a run ---------------------------------------------------------------------------------------------


class _FailingCamera(ScriptedWorld):
    """The scripted world with a camera image in its observations, failing at 1.2 s."""

    def observe(self) -> Observation:
        obs = super().observe()
        if obs.t > 1.2:
            raise RuntimeError("camera driver crashed")
        obs.sensors["image"] = _image(obs.t, int(obs.t * 100))
        return obs


def test_a_failed_run_keeps_the_frames_written_before_it_failed(tmp_path: Path) -> None:
    from taskflow.execution.runtime import run_mission
    from taskflow.execution.scripted import _IdleTask

    mission = load_mission(TOY)
    robot = mission.build_robot()
    world = _FailingCamera(robot, Script(metrics=lambda s: {"pos_error": 1.0, "visible": 1.0}), mission)
    result = run_mission(mission, world=world, task_factory=lambda cls, ctx: _IdleTask(ctx),
                         on_start=lambda ex: setattr(world, "executor", ex), out_dir=tmp_path / "run", max_time=10)
    assert result.outcome == "aborted" and "camera driver crashed" in result.summary["reason"]
    frames = read_frames(tmp_path / "run")
    assert [f.t for f in frames] == [0.0, 0.5, 1.0]  # the toy runs at 20 Hz: due times hit exactly
    assert all((tmp_path / "run" / f.file).is_file() for f in frames)


def test_a_world_without_images_records_no_frames(tmp_path: Path) -> None:
    drive(load_mission(TOY), Script(metrics=lambda s: {"pos_error": 0.0, "visible": 1.0},
                                    actions={"tool": (0.2, "tool_done")}), max_time=60, out_dir=tmp_path / "run")
    assert not (tmp_path / "run" / "frames.jsonl").exists() and not (tmp_path / "run" / "frames").exists()


def test_a_rendered_run_writes_frames_at_the_declared_rate(rendered_run_dir: Path) -> None:
    frames = read_frames(rendered_run_dir)
    ticks = len((rendered_run_dir / "trace.csv").read_text().splitlines()) - 1
    assert ticks > 3 * RATE  # 3 s run plus the safe stop
    # due every 1/2 s of the 3 s run, taken by the first 25 Hz tick at or after it
    due = [n / DEFAULT_HZ for n in range(6)]
    expected_ticks = [int(np.ceil(d * RATE - 1e-9)) for d in due]
    assert [f.tick for f in frames] == expected_ticks
    assert [f.t for f in frames] == pytest.approx([k / RATE for k in expected_ticks])
    assert {f.sensor for f in frames} == {"image"} and all(f.stamp <= f.t + 1e-9 for f in frames)
    for f in frames:
        px = cv2.imread(str(rendered_run_dir / f.file), cv2.IMREAD_UNCHANGED)
        assert px.shape == (48, 64, 3) and (f.width, f.height) == (64, 48)
        assert px.std() > 1.0  # a rendered room, not a blank frame


def test_the_same_seed_writes_the_same_frames_byte_for_byte(rendered_run_dir: Path, tmp_path: Path) -> None:
    again = rendered_run(tmp_path / "again")
    a, b = read_frames(rendered_run_dir), read_frames(again)
    assert a == b and a
    for f in a:
        assert (rendered_run_dir / f.file).read_bytes() == (again / f.file).read_bytes()
    assert (rendered_run_dir / "frames.jsonl").read_bytes() == (again / "frames.jsonl").read_bytes()


@pytest.mark.mission
def test_frames_off_records_none(tmp_path: Path) -> None:
    from conftest import RENDERED, RENDERED_LOW_RES

    from taskflow.execution.runtime import run_mission

    run_mission(load_mission(RENDERED, RENDERED_LOW_RES), seed=5, max_time=0.5, out_dir=tmp_path / "run",
                frames_hz=0)
    assert read_frames(tmp_path / "run") == [] and not (tmp_path / "run" / "frames").exists()


# -- served and exported ----------------------------------------------------------------------------------


def test_the_view_serves_the_frame_nearest_a_time(rendered_run_dir: Path) -> None:
    frames = read_frames(rendered_run_dir)
    server = serve_replay(rendered_run_dir, "127.0.0.1:0")
    try:
        with urllib.request.urlopen(server.url + "/view/frames?since=0", timeout=10) as r:
            listed = json.loads(r.read())
        assert listed["next"] == len(frames) and listed["records"][1] == frames[1].as_dict()
        for t, want in ((1.1, frames[2]), (1.4, frames[3]), (None, frames[-1])):
            query = "sensor=image" + ("" if t is None else f"&t={t}")
            with urllib.request.urlopen(f"{server.url}/view/frame?{query}", timeout=10) as r:
                assert r.headers["Content-Type"] == "image/png"
                assert float(r.headers["X-Frame-Stamp"]) == want.stamp
                assert r.read() == (rendered_run_dir / want.file).read_bytes()
        for query, code, says in (("sensor=depth&t=1", 404, "recorded: image"), ("sensor=image&t=soon", 400, "sim time")):
            with pytest.raises(urllib.error.HTTPError) as err:
                urllib.request.urlopen(f"{server.url}/view/frame?{query}", timeout=10)
            assert err.value.code == code and says in json.loads(err.value.read())["error"]
    finally:
        server.stop()


def test_the_mcap_export_holds_the_frames_as_compressed_images_on_sim_time(rendered_run_dir: Path,
                                                                          tmp_path: Path) -> None:
    from mcap.reader import make_reader

    out = export_run(rendered_run_dir, out=tmp_path / "t.mcap")
    frames = read_frames(rendered_run_dir)
    with open(out, "rb") as f:
        got = [(s.name, s.encoding, c.message_encoding, m.log_time, json.loads(m.data))
               for s, c, m in make_reader(f).iter_messages(topics=["/camera/image"], log_time_order=True)]
    assert len(got) == len(frames)
    for (schema, enc, menc, log_time, msg), fr in zip(got, frames):
        assert (schema, enc, menc) == ("foxglove.CompressedImage", "jsonschema", "json")
        ns = round(fr.stamp * 1e9)
        assert log_time == ns and msg["timestamp"] == {"sec": ns // 10**9, "nsec": ns % 10**9}
        assert msg["format"] == "png" and msg["frame_id"] == "camera"
        assert base64.b64decode(msg["data"]) == (rendered_run_dir / fr.file).read_bytes()
