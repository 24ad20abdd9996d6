"""A plugin written against the public API loads unchanged: a tiny package built OUTSIDE the repository (a
robot, a world and a task using ``taskflow.api``, ``taskflow.registry``, ``taskflow.spatial`` and
``taskflow.messages``, found through its entry points), installed with pip into a folder of its own, and a
mission run with it by ``python -m taskflow.cli run`` in a fresh process.

This is the contract the framework's packages (``taskflow.mission``, ``taskflow.execution``, ...) must keep
whatever moves inside them: only the public modules' import paths are promised (issue 21)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

PLUGIN = '''
"""A planar point driven to a goal: the smallest robot + world + task a user would write."""

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from pydantic import Field

from taskflow import spatial
from taskflow.api import Observation, Robot, StepResult, StrictModel, Task, TaskContext, World, message
from taskflow.messages import Odometry
from taskflow.registry import describe_choices


class DotParams(StrictModel):
    v_max: float = Field(1.0, gt=0)


class Dot(Robot):
    """A point that moves at the commanded body velocity (v_x, v_y)."""

    Params = DotParams
    command_keys: ClassVar[dict[str, int]] = {"v": 2}


class PlaneParams(StrictModel):
    yaw: float = 0.5


class Plane(World):
    """A plane with a point robot on it, its odometry published as a ``taskflow.messages.Odometry``."""

    Params = PlaneParams
    ground_truth_keys = ("x", "y")
    observations: ClassVar[dict[str, Any]] = {"sensors.odom": message(Odometry, optional=False)}
    physics_hz = 100.0

    def reset(self) -> None:
        self.xy = np.zeros(2)
        self.v = np.zeros(2)
        self.k = 0

    def observe(self) -> Observation:
        t = self.k / self.physics_hz
        pose = (float(self.xy[0]), float(self.xy[1]), self.params.yaw)
        return Observation(t, sensors={"odom": Odometry(stamp=t, frame="odom", pose=pose)})

    def apply(self, command: Mapping[str, np.ndarray]) -> None:
        v_body = np.clip(command["v"], -self.robot.params.v_max, self.robot.params.v_max)
        self.v = spatial.rotation_z(self.params.yaw)[:2, :2] @ v_body

    def advance(self, dt: float) -> None:
        for _ in range(round(dt * self.physics_hz)):
            self.k += 1
            self.xy = self.xy + self.v / self.physics_hz

    def ground_truth(self) -> dict[str, float]:
        return {"x": float(self.xy[0]), "y": float(self.xy[1])}


class GoalParams(StrictModel):
    goal: tuple[float, float]
    gain: float = 2.0


class DotGoto(Task[GoalParams, DotParams]):
    """A P controller to ``goal`` in the odometry frame, commanded in the body frame."""

    Params = GoalParams
    robot_params = DotParams
    metrics = {"pos_error": "m"}
    requires: ClassVar[dict[str, Any]] = {"sensors.odom": message(Odometry, optional=False)}

    def __init__(self, ctx: TaskContext[GoalParams, DotParams]) -> None:
        super().__init__(ctx)
        self.goal = np.asarray(ctx.params.goal, dtype=float)
        assert describe_choices("dot_goto", ["dot_goto"]) is not None

    def step(self, obs: Observation) -> StepResult:
        odom = obs.sensors["odom"]
        x, y, yaw = odom.pose
        e_odom = self.goal - np.array([x, y])
        e_body = spatial.rotation_z(yaw)[:2, :2].T @ e_odom
        return StepResult({"v": self.ctx.params.gain * e_body}, {"pos_error": float(np.linalg.norm(e_odom))})
'''

ENTRY_POINTS = '''
[taskflow.robots]
outside_dot = tf_outside_plugin:Dot

[taskflow.worlds]
outside_plane = tf_outside_plugin:Plane

[taskflow.tasks]
outside_goto = tf_outside_plugin:DotGoto
'''

PYPROJECT = '''
[build-system]
requires = []
build-backend = "backend"
backend-path = ["."]
'''

BACKEND = '''
"""A PEP 517 backend of a few lines, so that building the plugin needs neither the network nor the ``wheel``
package (the pinned setuptools needs it for ``bdist_wheel``): the package folder and a dist-info with the
entry points, zipped as a wheel."""

import base64, hashlib, pathlib, zipfile

NAME, VERSION = "tf_outside_plugin", "0.1"
DIST = f"{NAME}-{VERSION}.dist-info"
META = {"METADATA": f"Metadata-Version: 2.1\\nName: tf-outside-plugin\\nVersion: {VERSION}\\n",
        "WHEEL": "Wheel-Version: 1.0\\nGenerator: backend\\nRoot-Is-Purelib: true\\nTag: py3-none-any\\n",
        "entry_points.txt": pathlib.Path("entry_points.txt").read_text()}


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    name = f"{NAME}-{VERSION}-py3-none-any.whl"
    files = {str(p): p.read_bytes() for p in sorted(pathlib.Path(NAME).rglob("*.py"))}
    files.update({f"{DIST}/{k}": v.encode() for k, v in META.items()})
    record = []
    with zipfile.ZipFile(pathlib.Path(wheel_directory) / name, "w") as whl:
        for arc, data in files.items():
            whl.writestr(arc, data)
            digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
            record.append(f"{arc},sha256={digest},{len(data)}")
        whl.writestr(f"{DIST}/RECORD", "\\n".join(record + [f"{DIST}/RECORD,,"]) + "\\n")
    return name
'''

MISSION = '''
mission: outside_plugin
robot: outside_dot
world: {name: outside_plane, params: {yaw: 0.5}}
rate_hz: 20
max_time: 30 s
machine:
  initial: go
  states:
    go:
      task: {name: outside_goto, params: {goal: [1.0, -0.5]}}
      transitions:
        - {to: done, when: pos_error < 1 cm}
    done: {final: succeeded}
'''


@pytest.fixture(scope="module")
def plugin_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The plugin's source in a temporary folder, installed with pip into another (``--target``)."""
    root = tmp_path_factory.mktemp("outside")
    src = root / "src"
    (src / "tf_outside_plugin").mkdir(parents=True)
    (src / "tf_outside_plugin" / "__init__.py").write_text(textwrap.dedent(PLUGIN))
    (src / "pyproject.toml").write_text(textwrap.dedent(PYPROJECT))
    (src / "backend.py").write_text(textwrap.dedent(BACKEND))
    (src / "entry_points.txt").write_text(textwrap.dedent(ENTRY_POINTS))
    target = root / "site"
    r = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation",
                        "--no-index", "--target", str(target), str(src)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    return target


def test_a_plugin_package_outside_the_repository_runs_a_mission(plugin_dir: Path, tmp_path: Path) -> None:
    mission = tmp_path / "outside.yaml"
    mission.write_text(textwrap.dedent(MISSION))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(plugin_dir), os.environ.get("PYTHONPATH")]))}
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "taskflow.cli", "run", str(mission), "--out", str(out), "--quiet"],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "succeeded", summary
    assert summary["metrics"]["pos_error"] < 0.01
    assert not str(Path(summary["file"])).startswith(str(Path(__file__).resolve().parents[1] / "missions"))


def test_the_plugin_is_in_the_catalogue(plugin_dir: Path, tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(plugin_dir), os.environ.get("PYTHONPATH")]))}
    r = subprocess.run([sys.executable, "-m", "taskflow.cli", "describe", "outside_goto", "--json"], cwd=tmp_path,
                       env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    entry = json.loads(r.stdout)
    assert entry["name"] == "outside_goto" and "outside_plane" in json.dumps(entry)
