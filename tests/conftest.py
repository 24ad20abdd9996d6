import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

import toys

toys.register()


import pytest  # noqa: E402

RENDERED = Path(__file__).resolve().parent.parent / "missions" / "visual_path_pose_regulation.yaml"
RENDERED_LOW_RES = ["robot.params.camera.width=64", "robot.params.camera.height=48"]


def rendered_run(out: Path, seed: int = 5, max_time: float = 3.0) -> Path:
    """A short run of a rendered world (the quadcopter's ``quad_room``, perception ``rendered``, a 64x48
    camera) recording its frames at the default rate into ``out``."""
    from taskflow.execution.runtime import run_mission
    from taskflow.mission.loader import load_mission

    run_mission(load_mission(RENDERED, RENDERED_LOW_RES), seed=seed, max_time=max_time, out_dir=out)
    return out


@pytest.fixture(scope="session")
def rendered_run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One short rendered run with camera frames, shared by the tests that read frames."""
    return rendered_run(tmp_path_factory.mktemp("rendered") / "run")
