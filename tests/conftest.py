import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

import toys
from lsp_session import client, toy_client  # noqa: F401  the language server's fixtures (tests/lsp)

toys.register()


from collections.abc import Callable, Iterator  # noqa: E402
from typing import TYPE_CHECKING, Any  # noqa: E402

import pytest  # noqa: E402

if TYPE_CHECKING:
    from control_live import LiveRun

    from taskflow.execution.summary import RunResult

# -- test tiers (README "Testing", docs/design.md "Testing") -------------------------------------------------
TIERS = ("unit", "machine", "sim", "mission", "browser", "cluster")
"""The tier markers, each registered with what it means in pyproject.toml (`--strict-markers`)."""

_FOLDER_TIER = {"unit": "unit", "machine": "machine", "sim": "sim", "missions": "mission"}
"""A test under ``tests/<folder>/`` (at any depth) has this tier."""

_FILE_TIER = {
    "test_plugin_outside.py": "mission", "test_lock.py": "unit", "test_registry.py": "unit", "test_testing_api.py": "unit", "test_yaml_fast_path.py": "unit",
    "test_batch_progress.py": "machine", "test_broken_missions.py": "machine", "test_campaign.py": "machine",
    "test_campaign_plots.py": "machine", "test_catalogue.py": "machine", "test_cli.py": "machine",
    "test_cli_bad_input.py": "machine", "test_compare_run_numbers.py": "machine", "test_control.py": "machine",
    "test_control_runs.py": "machine",
    "test_control_auth.py": "machine", "test_dependency_direction.py": "machine", "test_frames.py": "machine",
    "test_graph.py": "machine", "test_hostile_records.py": "machine", "test_loader_extras.py": "machine",
    "test_operator_semantics.py": "machine", "test_properties_machines.py": "machine", "test_properties_mutations.py": "machine",
    "test_properties_operated.py": "machine", "test_properties_regions.py": "machine", "test_records_readers.py": "machine",
    "test_report.py": "machine", "test_seam_submission.py": "machine", "test_view.py": "machine",
    "test_conformance.py": "sim",
    "test_frames_worlds.py": "mission", "test_journeys.py": "mission", "test_packaging.py": "mission",
    "test_plots.py": "mission", "test_signals.py": "mission", "test_telemetry.py": "mission",
    "test_view_browser.py": "browser",
    "test_ray_backend.py": "cluster",
}
"""The tier of each test module outside the tier folders (directly in ``tests/`` or in a folder mirroring a
framework package: ``tests/mission/``, ``tests/execution/``, ...), by file name (read from what the module does)."""

_MISSION_FIXTURES = frozenset({"rendered_run_dir"})
"""Fixtures that run a mission on PyBullet: a unit or machine test using one is a mission test."""


def tier_of(item: pytest.Item) -> str:
    """The tier of a collected test: its own marker or its module's ``pytestmark`` if it has one, else its
    folder's or its module's, raised to ``mission`` for a unit or machine test using a mission fixture."""
    own = [m.name for m in item.iter_markers() if m.name in TIERS]
    if own:
        return own[0]
    rel = item.path.relative_to(Path(__file__).parent)
    if len(rel.parts) > 1 and rel.parts[0] in _FOLDER_TIER:
        tier = _FOLDER_TIER[rel.parts[0]]
    elif rel.name in _FILE_TIER:
        tier = _FILE_TIER[rel.name]
    else:
        raise pytest.UsageError(f"tests/{rel.as_posix()} has no tier: add it to _FILE_TIER in tests/conftest.py "
                                f"(one of {', '.join(TIERS)}) or give it a `pytestmark`")
    if tier in ("unit", "machine") and any(f in _MISSION_FIXTURES for f in getattr(item, "fixturenames", ())):
        return "mission"
    return tier


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        tier = tier_of(item)
        if not any(m.name == tier for m in item.iter_markers()):
            item.add_marker(getattr(pytest.mark, tier))


@pytest.fixture(autouse=True)
def _unit_tests_start_no_simulator(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> None:
    """A unit test that connects to PyBullet fails, naming the tier it belongs to."""
    if request.node.get_closest_marker("unit") is None:
        return
    import pybullet

    def refuse(*args: object, **kwargs: object) -> int:
        raise RuntimeError(f"{request.node.nodeid} starts PyBullet: it is not a unit test (mark it sim or mission)")

    monkeypatch.setattr(pybullet, "connect", refuse)

RENDERED = Path(__file__).resolve().parent.parent / "missions" / "visual_path_pose_regulation.yaml"
RENDERED_LOW_RES = ["robot.params.camera.width=64", "robot.params.camera.height=48"]


def rendered_run(out: Path, seed: int = 5, max_time: float = 3.0) -> Path:
    """A short run of a rendered world (the quadcopter's ``quad_room``, perception ``rendered``, a 64x48
    camera) recording its frames at the default rate into ``out``."""
    from taskflow.execution.runtime import run_mission
    from taskflow.mission.loader import load_mission

    run_mission(load_mission(RENDERED, RENDERED_LOW_RES), seed=seed, max_time=max_time, out_dir=out)
    return out


@pytest.fixture
def register() -> Iterator[Callable[[Any, str, type], None]]:
    """``register(REGISTRY, name, cls)`` for one test: what it adds is removed afterwards, so no later test of the
    process (the suite runs in a few of them, ``-n auto``) sees a longer list of valid names in its messages."""
    added: list[tuple[Any, str]] = []

    def add(registry: Any, name: str, cls: type) -> None:
        if name not in registry._items:
            registry.add(name, cls)
            added.append((registry, name))

    yield add
    for registry, name in reversed(added):
        registry.remove(name)


@pytest.fixture(scope="session")
def rendered_run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One short rendered run with camera frames, shared by the tests that read frames."""
    return rendered_run(tmp_path_factory.mktemp("rendered") / "run")


@pytest.fixture
def live() -> Iterator[Callable[..., "LiveRun"]]:
    """Start a run in a thread with its control endpoint (tests/control_live.py); a run a failed test leaves
    behind is pre-empted at teardown."""
    from control_live import LiveRun

    from taskflow.execution.control import ControlError

    runs: list[LiveRun] = []

    def start(fn: Callable[[], "RunResult"], run_dir: Path) -> LiveRun:
        run = LiveRun(fn, run_dir)
        runs.append(run)
        return run

    yield start
    for run in runs:  # a failed test must not leave a paused run behind
        if run.thread.is_alive():
            try:
                run.client.send("preempt", who="teardown")
            except ControlError:
                pass
            run.thread.join(10)
