"""Campaign figures label every axis ``name [unit]`` as the run figures do: a metric's unit from the
mission's declarations (or its name's suffix), a swept key's from its parameter's declaration or the unit
its values are written in.  Real batches: the toy mission, and the racecar on PyBullet for world and
robot parameters."""

from __future__ import annotations

from pathlib import Path

import pytest

from taskflow.campaigns import campaign_plots
from taskflow.campaigns.batch import run_batch
from taskflow.campaigns.campaign_plots import campaign_figures, metric_unit, plot_campaign, plot_success_comparison
from taskflow.campaigns.compare import load_batch
from taskflow.mission.loader import load_mission

HERE = Path(__file__).resolve().parents[1]
TOY = HERE / "machine" / "missions" / "toy_full.yaml"
CAR = HERE.parent / "missions" / "car_waypoints.yaml"


def _labels(figures: list[tuple[str, object]]) -> dict[str, tuple[str, str]]:
    """file name → (x label, y label) of each figure's axes."""
    out = {}
    for name, fig in figures:
        ax = fig.axes[0]  # type: ignore[attr-defined]
        out[name] = (ax.get_xlabel(), ax.get_ylabel())
    return out


@pytest.fixture(scope="module")
def toy_batch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("toy") / "b"
    run_batch(str(TOY), trials=2, workers=1, seed=1, out=out,
              sweep=["parameters.tol=1 cm,2 cm", "world.params.tool_ok=true,false"])
    return out


def test_a_swept_quantity_is_drawn_in_its_base_unit_and_the_metric_with_its_declared_unit(toy_batch: Path) -> None:
    batch = load_batch(toy_batch)
    assert "pos_error" in {k for t in batch["trials"] for k in t["metrics"]}  # toy_goto declares it in m
    figures = campaign_figures(batch, ["pos_error"])
    labels = _labels(figures)
    assert labels["success_vs_parameters_tol.png"] == ("parameters.tol [m]", "mission success [%] (95 % Wilson interval)")
    # a boolean parameter declares no unit: dimensionless
    assert labels["success_vs_world_params_tool_ok.png"][0] == "world.params.tool_ok [-]"
    assert labels["distribution_pos_error.png"] == ("parameters.tol [m], world.params.tool_ok [-]", "pos_error [m]")
    ax = dict(figures)["success_vs_parameters_tol.png"].axes[0]  # type: ignore[attr-defined]
    xs = sorted({round(float(x), 9) for line in ax.get_lines() for x in line.get_xdata()})
    assert xs == [0.01, 0.02]  # "1 cm", "2 cm" at their values in metres, not at category positions 0, 1
    assert [p.name for p in plot_campaign(toy_batch, ["pos_error"])] == [name for name, _ in figures]


def test_without_the_mission_the_units_come_from_the_names(toy_batch: Path) -> None:
    batch = dict(load_batch(toy_batch), file=str(toy_batch / "moved_away.yaml"))
    labels = _labels(campaign_figures(batch, ["pos_error"]))
    assert labels["distribution_pos_error.png"][1] == "pos_error [?]"  # not known, never guessed
    assert labels["success_vs_parameters_tol.png"][0] == "parameters.tol [m]"  # the values say it
    assert labels["success_vs_world_params_tool_ok.png"][0] == "world.params.tool_ok [?]"
    assert metric_unit("sim_time_s", None) == "s" and metric_unit("gt_speed_mps", None) == "m/s"


@pytest.mark.mission
def test_world_and_robot_parameters_carry_their_declared_units(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # the racecar on PyBullet, one trial per condition cut to 0.5 s simulated
    a, b = tmp_path / "a", tmp_path / "b"
    sweep = ["world.params.odom_noise=0,0.01", "robot.params.front_camera.rate_hz=10,15"]
    run_batch(str(CAR), trials=1, workers=1, out=a, max_time=0.5, sweep=sweep)
    labels = _labels(campaign_figures(load_batch(a)))
    assert labels["success_vs_world_params_odom_noise.png"][0] == "world.params.odom_noise [m]"
    assert labels["success_vs_robot_params_front_camera_rate_hz.png"][0] == "robot.params.front_camera.rate_hz [Hz]"
    units = load_mission(CAR).metric_units
    for metric in ("pos_error", "heading_error"):
        assert labels[f"distribution_{metric}.png"] == (
            "world.params.odom_noise [m], robot.params.front_camera.rate_hz [Hz]", f"{metric} [{units[metric]}]")
    assert units["heading_error"] == "rad"
    run_batch(str(CAR), trials=1, workers=1, out=b, max_time=0.5, sweep=sweep, seed=7)
    drawn: list[str] = []
    save = campaign_plots._save
    monkeypatch.setattr(campaign_plots, "_save", lambda fig, path: (drawn.append(fig.axes[0].get_xlabel()), save(fig, path))[1])
    fig = plot_success_comparison([("a", load_batch(a)), ("b", load_batch(b))], tmp_path / "both.png")
    assert fig.stat().st_size > 0 and drawn == ["world.params.odom_noise [m]"]
