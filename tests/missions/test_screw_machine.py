"""The screw-fastening machine (REFERENCE.md §2) driven by taskflow.testing scripts: exact paths,
resume after a lost marker, timeouts, coupling failures, profiles per state, load-time errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import taskflow_robots.mobile_iiwa  # noqa: F401 - registers mobile_iiwa
import taskflow_sim.screw.world  # noqa: F401 - registers screw_conveyor
import taskflow_tasks.screw.mobile_pbvs  # noqa: F401 - registers the pbvs tasks

from taskflow.errors import MissionError
from taskflow.mission.loader import load_mission
from taskflow.testing import Script, assert_outcome, assert_path, drive, time_in

ROOT = Path(__file__).resolve().parents[2]
CONVEYOR = ROOT / "missions" / "screw_fastening.yaml"
TROLLEY = ROOT / "missions" / "screw_fastening_trolley.yaml"

S = "cell.operation.operate.screws."  # the operation region of the parallel state `cell`
OP = "cell.operation."
PER_SCREW = [S + "s2_arm_approach", S + "s3_arm_destination_approach", S + "s4_tool_activation",
             S + "s5_operation", S + "s6_arm_retract", S + "screw_fastened"]
FULL_PATH = ([OP + "initial_search", "cell.safety.watch", "cell.operation.operate.s1_platform_approach"] + PER_SCREW * 4
             + [OP + "operate.s7_final_arm_retract", OP + "operate.s8_final_platform_retract", OP + "operate.done",
                OP + "fastened", "success"])


def converging(s) -> dict[str, float]:  # type: ignore[no-untyped-def]
    """Every error falls linearly to zero in one second after its state is entered."""
    k = max(0.0, 1.0 - s.time_in_state)
    return {"camera_error.t": 0.1 * k, "camera_error.r": 0.05 * k, "ee_error.t": 0.05 * k, "ee_error.r": 0.02 * k,
            "joint_error": 0.5 * k}


def screwdriver(fail_on: set[int] | None = None):  # type: ignore[no-untyped-def]
    """Activation 1 s (coupling fails on the given activations, counted from 1), fastening its duration."""
    count = {"activate": 0}

    def action(params):  # type: ignore[no-untyped-def]
        if params.get("phase") == "fasten":
            return float(params["duration"]), "screw_done"
        count["activate"] += 1
        return 1.0, "tool_failed" if fail_on and count["activate"] in fail_on else "tool_activated"

    return action


@pytest.fixture(scope="module")
def mission():
    return load_mission(CONVEYOR)


def test_exact_path_for_four_screws(mission):
    r = drive(mission, Script(metrics=converging, events=[(0.1, "target_found")],
                              actions={"screwdriver": screwdriver()}), max_time=120)
    assert_outcome(r, "succeeded")
    assert_path(r, FULL_PATH)
    its = r.summary["iterations"]
    assert [it["outcome"] for it in its] == ["succeeded"] * 4
    assert [it["item"] for it in its] == mission.spec.parameters["screws"]
    # s5 lasts the fastening duration the action was given (t of the paper's table)
    assert time_in(r, S + "s5_operation") == pytest.approx(4 * 3.0, abs=0.05)


def test_each_state_binds_the_profiles_of_the_table(mission):
    table = {  # state: (platform, arm, impedance) — REFERENCE.md §2
        "cell.operation.operate.s1_platform_approach": ("platform_boost", "arm_zero", "stiff"),
        S + "s2_arm_approach": ("platform_operate", "arm_boost", "stiff"),
        S + "s3_arm_destination_approach": ("platform_operate", "arm_operate", "compliant"),
        S + "s4_tool_activation": ("platform_operate", "arm_operate", "compliant"),
        S + "s5_operation": ("platform_operate", "arm_operate", "compliant"),
        S + "s6_arm_retract": ("platform_operate", "arm_boost", "compliant"),
        "cell.operation.operate.s7_final_arm_retract": ("platform_boost", "arm_operate", "stiff"),
        "cell.operation.operate.s8_final_platform_retract": ("platform_boost", "arm_zero", None),
    }
    prof = mission.spec.profiles
    for path, (pb, pa, imp) in table.items():
        node = mission.states[path]
        assert node.profiles["platform"].model_dump() == type(node.profiles["platform"]).model_validate(prof["pid"][pb]).model_dump(), path
        assert node.profiles["arm"].model_dump() == type(node.profiles["arm"]).model_validate(prof["pid"][pa]).model_dump(), path
        if imp is None:
            assert "impedance" not in node.profiles, path
        else:
            assert node.profiles["impedance"].model_dump() == type(node.profiles["impedance"]).model_validate(prof["impedance"][imp]).model_dump(), path
    assert mission.states[OP + "operate"].history
    # searching follows the predicted part with s5's sets, or stops (prediction off: the paper's stop)
    node = mission.states[OP + "searching"]
    assert node.task_cls is not None and node.task_cls.__name__ == "PbvsFollow"
    for slot, name in (("platform", "platform_operate"), ("arm", "arm_operate")):
        assert node.profiles[slot].model_dump() == type(node.profiles[slot]).model_validate(prof["pid"][name]).model_dump()
    assert node.profiles["prediction"].model_dump() == mission.states[S + "s5_operation"].profiles["prediction"].model_dump()


def test_marker_lost_in_s3_for_one_second_resumes_s3_of_the_same_screw(mission):
    base = Script(metrics=converging, events=[(0.1, "target_found")], actions={"screwdriver": screwdriver()})
    dry = drive(mission, base, max_time=120)
    s3_second = [tr.t for tr in dry.executor.transitions_fired if tr.target == S + "s3_arm_destination_approach"][1]
    lost = s3_second + 0.5
    seen: list[tuple[float, object]] = []  # (time, screw item) on every s3 tick

    def metrics(s):  # type: ignore[no-untyped-def]
        m = converging(s)
        if "searching" in s.state:  # the marker seen again (pbvs_follow's flag) from the target_found on
            m["target_seen"] = float(s.t >= lost + 1.0)
        if "s3_arm_destination_approach" in s.state:
            seen.append((s.t, s.items.get("screw")))
            if s3_second <= s.t < lost + 1.0:
                m["ee_error.t"] = 0.01  # the second screw's s3 has not converged before the loss
        return m

    r = drive(mission, Script(metrics=metrics, events=[(0.1, "target_found"), (lost, "target_lost"), (lost + 1.0, "target_found")],
                              actions={"screwdriver": screwdriver()}), max_time=120)
    assert_outcome(r, "succeeded")
    path = r.summary["states_visited"]
    i = path.index(OP + "searching")
    assert path[i - 1] == path[i + 1] == S + "s3_arm_destination_approach"
    assert path.count(S + "s2_arm_approach") == 4  # the screw was not restarted from its approach
    assert time_in(r, OP + "searching") == pytest.approx(1.0, abs=0.02)
    second = mission.spec.parameters["screws"][1]
    before = [it for t, it in seen if s3_second <= t < lost]
    after = [it for t, it in seen if lost + 1.0 <= t < lost + 1.5]
    assert before and after and all(it == second for it in before + after)
    assert [it["outcome"] for it in r.summary["iterations"]] == ["succeeded"] * 4


def test_marker_found_again_resumes_only_once_the_camera_is_within_the_approach_threshold(mission):
    """After a loss the interrupted state resumes when the marker is seen again *and* the platform's camera
    error is back under the approach threshold (2 cm): not while it is off — so the screwdriver is never
    restarted on a part that moved away (the property tool_only_when_aligned)."""
    lost, found, aligned = 5.0, 6.0, 6.8

    def metrics(s):  # type: ignore[no-untyped-def]
        m = converging(s)
        if "searching" in s.state:
            m["target_seen"] = float(s.t >= found)
            m["camera_error.t"] = 0.05 if s.t < aligned else 0.005  # 5 cm off until the platform re-aligned
        return m

    r = drive(mission, Script(metrics=metrics, events=[(0.1, "target_found"), (lost, "target_lost"), (found, "target_found")],
                              actions={"screwdriver": screwdriver()}), max_time=120)
    assert_outcome(r, "succeeded")
    into = [tr for tr in r.executor.transitions_fired if tr.state == OP + "searching"]
    assert len(into) == 1 and into[0].t == pytest.approx(aligned, abs=0.02)
    assert time_in(r, OP + "searching") == pytest.approx(aligned - lost, abs=0.02)


def test_marker_lost_beyond_the_timeout_ends_in_error_through_the_controlled_stop(mission):
    lost = 5.0
    script = Script(metrics=converging, events=[(0.1, "target_found"), (lost, "target_lost")],
                    actions={"screwdriver": screwdriver()})
    worlds = []
    r = drive(mission, script, max_time=120, on_world=worlds.append)
    assert_outcome(r, "failed")
    path = r.summary["states_visited"]
    assert path[-3:] == [OP + "searching", "error_stop", "error"]
    assert time_in(r, OP + "searching") == pytest.approx(3.0, abs=0.02)  # the searching timeout
    # from the loss on, the platform is commanded to stand still
    world = worlds[0]
    k = round(lost * mission.spec.rate_hz)
    assert all(not np.any(c["base_twist"]) for c in world.applied[k:])


def test_initial_search_times_out_into_error(mission):
    r = drive(mission, Script(metrics=converging), max_time=60)
    assert_outcome(r, "failed")
    assert r.summary["states_visited"] == [OP + "initial_search", "cell.safety.watch", "error_stop", "error"]
    assert time_in(r, OP + "initial_search") == pytest.approx(10.0, abs=0.02)


def test_a_failed_tool_activation_is_retracted_from_and_retried(mission):
    """The second screw's first activation fails: the tool retracts to the approach pose, the attempt ends
    `attempt_failed`, and the loop runs the screw again from s2 (issue 25) — which fastens it."""
    r = drive(mission, Script(metrics=converging, events=[(0.1, "target_found")],
                              actions={"screwdriver": screwdriver(fail_on={2})}), max_time=120)
    assert_outcome(r, "succeeded")
    path = r.summary["states_visited"]
    retracted = [S + "s2_arm_approach", S + "s3_arm_destination_approach", S + "s4_tool_activation",
                 S + "retract_to_retry", S + "attempt_failed"]
    assert path[3 + 6:3 + 6 + 5 + 6] == retracted + PER_SCREW  # the second screw: retracted, then fastened
    retry = [rec.as_dict() for rec in r.executor.transitions_fired if rec.cause == "retry"]
    assert [(x["from"], x["to"], x["item"], x["attempt"]) for x in retry] == [
        (S + "attempt_failed", S + "s2_arm_approach", 1, 2)]
    assert [(it["outcome"], it["attempts"]) for it in r.summary["iterations"]] == [("succeeded", 1), ("succeeded", 2),
                                                                                  ("succeeded", 1), ("succeeded", 1)]
    items = r.summary["items"]["cell.operation.operate.screws"]
    assert (items["attempted"], items["succeeded"], items["attempts"], items["retried"]) == (4, 4, 5, 1)


def test_a_screw_whose_activation_fails_three_times_is_recorded_failed_and_the_sequence_goes_on(mission):
    r = drive(mission, Script(metrics=converging, events=[(0.1, "target_found")],
                              actions={"screwdriver": screwdriver(fail_on={2, 3, 4})}), max_time=200)
    its = r.summary["iterations"]
    assert [(it["outcome"], it["attempts"]) for it in its] == [("succeeded", 1), ("failed", 3), ("succeeded", 1),
                                                              ("succeeded", 1)]
    assert its[1]["retried"] == ["attempt_failed", "attempt_failed"]
    path = r.summary["states_visited"]
    assert path.count(S + "retract_to_retry") == 3 and path.count(S + "s5_operation") == 3
    # every screw was tried; 3 of 4 fastened does not meet the paper's criterion (all): controlled stop, failed
    assert r.summary["items"]["cell.operation.operate.screws"] == {
        "attempted": 4, "succeeded": 3, "failed": 1, "success_rate": 0.75, "required": 4, "rule": "all",
        "retry": 2, "attempts": 6, "retried": 1, "recovered": 0}
    assert path[-2:] == ["error_stop", "error"]
    assert_outcome(r, "failed")


def test_a_bit_that_slipped_while_fastening_is_retracted_from_and_retried(mission):
    """A failure in s5 (the bit slipped off: a marker lost beyond what searching follows, a jolt) retracts and
    retries the screw from s2 as a failed activation does (issue 25): the third screw slips once, then is
    fastened at its second attempt; the loop counts it once, succeeded."""
    count = {"fasten": 0}

    def slipping_once(params):  # type: ignore[no-untyped-def]
        if params.get("phase") != "fasten":
            return 1.0, "tool_activated"
        count["fasten"] += 1
        return (0.5, "tool_failed") if count["fasten"] == 3 else (float(params["duration"]), "screw_done")

    r = drive(mission, Script(metrics=converging, events=[(0.1, "target_found")], actions={"screwdriver": slipping_once}),
              max_time=120)
    assert_outcome(r, "succeeded")
    retry = [rec.as_dict() for rec in r.executor.transitions_fired if rec.cause == "retry"]
    assert [(x["from"], x["item"], x["attempt"]) for x in retry] == [(S + "attempt_failed", 2, 2)]
    path = r.summary["states_visited"]
    slipped = [S + "s2_arm_approach", S + "s3_arm_destination_approach", S + "s4_tool_activation", S + "s5_operation",
               S + "retract_to_retry", S + "attempt_failed"]
    assert path[3 + 12:3 + 12 + 6 + 6] == slipped + PER_SCREW
    assert [(it["outcome"], it["attempts"]) for it in r.summary["iterations"]] == [("succeeded", 1), ("succeeded", 1),
                                                                                  ("succeeded", 2), ("succeeded", 1)]


def test_a_bit_that_always_slips_fails_its_screw_after_three_attempts(mission):
    def slipping(params):  # type: ignore[no-untyped-def]
        return (1.0, "tool_activated") if params.get("phase") != "fasten" else (0.5, "tool_failed")
    r = drive(mission, Script(metrics=converging, events=[(0.1, "target_found")], actions={"screwdriver": slipping}),
              max_time=300)
    assert [(it["outcome"], it["attempts"]) for it in r.summary["iterations"]] == [("failed", 3)] * 4
    assert r.summary["states_visited"].count(S + "s5_operation") == 12
    assert_outcome(r, "failed")


def test_trolley_mission_has_the_same_machine():
    a, b = load_mission(CONVEYOR), load_mission(TROLLEY)
    assert set(a.states) == set(b.states)
    assert b.spec.world.params["motion"] == "trolley"
    r = drive(b, Script(metrics=converging, events=[(0.1, "target_found")], actions={"screwdriver": screwdriver()}),
              max_time=120)
    assert_path(r, FULL_PATH)


@pytest.mark.parametrize("override, expect", [
    ("profiles.pid.arm_boost.kp=[1, 2, 3]", "6 values"),
    ("profiles.pid.platform_operate.ki=[0, 0, 1, 1, 1, 0, 0]", "6 values"),
    ("parameters.screws=[]", "non-empty list"),
    ("parameters.screws=[[0.14, 0.06, 0.0075, 3.14, 0, -1.57], bolt]", "pose"),
    ("parameters.screws=[[0.14, 0.06, 0.0075, 3.14, 0, -1.57], [0.1, 0.2]]", "6 numbers"),
    ("profiles.impedance.compliant.K=[0.0, 300.0, 600.0]", "stiffness"),
    ("profiles.impedance.stiff.K=-5", "stiffness"),
    ("parameters.eps_t=1 deg", "eps_t"),
    ("parameters.eps_r_platform=2 mm", "eps_r_platform"),
])
def test_bad_input_is_a_clear_load_time_error(override, expect):
    with pytest.raises(MissionError) as exc:
        load_mission(CONVEYOR, [override])
    text = str(exc.value)
    assert expect in text, text
    assert "screw_fastening.yaml:" in text  # located in the file
