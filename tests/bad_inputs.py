"""Broken command-line inputs, each with the fragment its one-line message must hold.

Every case is a ``taskflow`` command on a shipped mission (so a fresh process can run it without
the test-only toy plugins).  ``tests/cli/test_cli_bad_input.py`` runs them in-process and checks the
message, the exit code 1 and the absence of a traceback; ``benchmarks/bad_input.py`` runs each in
a fresh process and prints its wall time and peak memory (the issue's 2 s / 200 MB budget).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from taskflow.mission.yamlsrc import MAX_NODES

ROOT = Path(__file__).resolve().parent.parent
CAR = str(ROOT / "missions" / "car_waypoints.yaml")
VIKI = str(ROOT / "missions" / "viki_hyco.yaml")
QUAD = str(ROOT / "missions" / "visual_path_pose_regulation.yaml")
SCREW = str(ROOT / "missions" / "screw_fastening.yaml")


@dataclass(frozen=True)
class BadInput:
    name: str
    argv: tuple[str, ...]
    fragment: str  # the message must contain it
    where: str = ""  # the line must start with it (FILE:LINE:COL, FILE: --set …, or "taskflow CMD: --flag")


def _states_file(tmp: Path, n: int) -> Path:
    lines = ["mission: huge", "robot: racecar", "world: flat_ground", "rate_hz: 20", "machine:", "  initial: s0",
             "  states:"]
    lines += [f"    s{i}: {{final: true}}" for i in range(n)]  # ~2 MB: under the size limit, over the node limit
    path = tmp / "huge.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def _with_guard(tmp: Path, guard: str, name: str) -> Path:
    text = Path(CAR).read_text()
    old = 'when: "pos_error < 3 cm"'
    assert old in text, "car_waypoints.yaml changed: update tests/bad_inputs.py"
    path = tmp / name
    path.write_text(text.replace(old, f"when: {guard!r}", 1))
    return path


def cases(tmp: Path) -> list[BadInput]:
    """Every case; files they need are written under ``tmp``."""
    zero = tmp / "zero.yaml"
    if not zero.exists():
        os.symlink("/dev/zero", zero)
    batch_dir = tmp / "a_batch"
    batch_dir.mkdir(exist_ok=True)
    (batch_dir / "batch.json").write_text("{}\n")
    deep = "(" * 200 + "pos_error < 1 cm" + ")" * 200
    nots = "not " * 5000 + "pos_error < 1 cm"
    out = [
        BadInput("max-time-nan", ("run", CAR, "--max-time", "nan"), "must be a finite", "taskflow run: --max-time"),
        BadInput("max-time-inf", ("run", CAR, "--max-time", "inf"), "must be a finite", "taskflow run: --max-time"),
        BadInput("max-time-huge", ("run", CAR, "--max-time", "1e308"), "≤ 86400 s", "taskflow run: --max-time"),
        BadInput("max-time-negative", ("run", CAR, "--max-time", "-5"), "must be > 0 s", "taskflow run: --max-time"),
        BadInput("max-time-unit", ("run", CAR, "--max-time", "30 deg"), "expected a time", "taskflow run: --max-time"),
        BadInput("set-max-time-nan", ("validate", CAR, "--set", "max_time=.nan"), "must be a finite",
                 f"{CAR}: --set max_time=.nan"),
        BadInput("physics-1-hz", ("validate", CAR, "--set", "world.params.physics_hz=1"), "greater than or equal to 100",
                 f"{CAR}: --set world.params.physics_hz=1"),
        BadInput("rates-do-not-divide", ("validate", CAR, "--set", "rate_hz=7"), "does not divide the physics rate 240 Hz",
                 f"{CAR}: --set rate_hz=7"),
        BadInput("rate-with-wrong-unit", ("validate", CAR, "--set", "rate_hz=20 s"), "expected a frequency",
                 f"{CAR}: --set rate_hz=20 s"),
        BadInput("distribution-support", ("validate", VIKI, "--set", "world.params.dropout={uniform: [0.5, 1.5]}"),
                 "uniform bound 1.5 is not a valid value here", f"{VIKI}: --set world.params.dropout"),
        BadInput("distribution-signed-support", ("validate", VIKI, "--set",
                                                 "world.params.dropout={signed_uniform: [0.1, 0.2]}"),
                 "signed_uniform bound -0.2 is not a valid value here", f"{VIKI}: --set world.params.dropout"),
        BadInput("distribution-normal-bounded", ("validate", VIKI, "--set", "world.params.dropout={normal: [0.2, 0.05]}"),
                 "normal [0.2, 0.05] (unbounded", f"{VIKI}: --set world.params.dropout"),
        BadInput("guard-syntax-in-set", ("validate", CAR, "--set",
                                         "machine.states.drive.states.settle.transitions.0.when=pos_error <"),
                 "the expression ends too early", f"{CAR}: --set machine.states.drive.states.settle.transitions.0.when"),
        BadInput("guard-deep-parentheses", ("validate", str(_with_guard(tmp, deep, "deep.yaml"))), "more than 32 levels",
                 f"{tmp / 'deep.yaml'}:"),
        BadInput("guard-not-chain", ("validate", str(_with_guard(tmp, nots, "nots.yaml"))), "more than 32 levels",
                 f"{tmp / 'nots.yaml'}:"),
        BadInput("device-file", ("validate", str(zero)), "is not a regular file", f"{zero}:"),
        BadInput("too-many-states", ("validate", str(_states_file(tmp, 100_000))), f"more than {MAX_NODES} YAML nodes",
                 f"{tmp / 'huge.yaml'}:1:1:"),
        BadInput("history-yes", ("validate", CAR, "--set", "machine.states.drive.history=yes"), "write true or false",
                 f"{CAR}: --set machine.states.drive.history=yes"),
        BadInput("quad-start-outside-room", ("validate", QUAD, "--set", "world.params.start=[40, 0, 1, 0]"),
                 "outside the room", f"{QUAD}: --set world.params.start"),
        BadInput("batch-zero-trials", ("batch", CAR, "--trials", "0"), "must be at least 1", "taskflow batch: --trials 0"),
        BadInput("batch-zero-workers", ("batch", CAR, "--trials", "2", "--workers", "0"), "must be at least 1",
                 "taskflow batch: --workers 0"),
        BadInput("batch-negative-workers", ("batch", CAR, "--trials", "2", "--workers", "-2"), "must be at least 1",
                 "taskflow batch: --workers -2"),
        BadInput("plot-missing-folder", ("plot", str(tmp / "nope")), "no such folder", f"taskflow plot: {tmp / 'nope'}"),
        BadInput("plot-batch-folder", ("plot", str(batch_dir)), "a batch folder", f"taskflow plot: {batch_dir}"),
    ]
    out += _operator_scripts(tmp)  # the "ops" block (issue 20): malformed operator scripts
    out += _seam_cases(tmp)  # issue 20, "load": sub-missions, --sweep/--set, numeric options, check
    out += _bound_cases()  # issue 20, "bounds": values the robot or world cannot honour, guards that never hold
    return out


# (name, script text, where in it: "LINE:COL", fragment) — each refused before the run starts, at its own position
_OPERATOR_SCRIPTS = [
    ("ops-yaml-syntax", "- {t: 1, action: pause\n", "2:1", "YAML error"),
    ("ops-empty", "", "1:1", "the operator script is empty"),
    ("ops-not-a-list", "pause: 1\n", "1:1", "an operator script is a list of actions"),
    ("ops-unknown-action", "- {t: 1, action: paws}\n", "1:10",
     "invalid value 'paws' — Input should be 'pause', 'hold'"),
    ("ops-unknown-argument", "- {t: 1, action: pause, args: {to: x}}\n", "1:3",
     "unknown argument 'to' (it takes none) — an item is {t, action, args, who}"),
    ("ops-argument-not-text", "- {t: 1, action: preempt, args: {to: [a]}}\n", "1:34",
     "a valid string — args: {to: STATE_PATH} for preempt"),
    ("ops-negative-t", "- {t: 1, action: hold}\n- {t: -1, action: resume}\n", "2:4",
     "greater than or equal to 0 — t is the sim time in seconds"),
    ("ops-infinite-t", "- {t: .inf, action: hold}\n", "1:4", "finite number"),
    ("ops-preempt-unknown-state", "- {t: 1, action: preempt, args: {to: drive.aproach}}\n", "1:34",
     "did you mean 'drive.approach'"),
    ("ops-inject-undeclared-event", "- {t: 1, action: inject, args: {event: arrived}}\n", "1:33",
     "event 'arrived' is not declared by mission 'car_waypoints'"),
    ("ops-pause-never-resumed", "- {t: 5, action: pause}\n- {t: 1, action: resume}\n", "1:10", "never resumed"),
]


def _operator_scripts(tmp: Path) -> list[BadInput]:
    out = []
    for name, text, where, fragment in _OPERATOR_SCRIPTS:
        path = tmp / f"{name}.yaml"
        path.write_text(text)
        argv = ("run", CAR, "--no-control", "--operator-script", str(path), "--out", str(tmp / f"{name}-run"))
        out.append(BadInput(name, argv, fragment, f"{path}:{where}:"))
    return out


# -- issue 20 ("load"): bad input where the newer features meet ---------------------------------------

_USING = """\
mission: ladder
robot: racecar
world: flat_ground
rate_hz: 20
machine:
  initial: a
  states:
    a:
      use: USE
      transitions: [{to: fin, done: true}]
    fin: {final: succeeded}
"""


def _ladder(tmp: Path, name: str, depth: int, fan_out: int) -> Path:
    """``name/m.yaml`` using ``l0.yaml``, each ``l{i}`` using ``l{i+1}`` ``fan_out`` times (a sub-mission
    ladder: depth ``depth``, ``fan_out ** depth`` uses in all), on the shipped racecar."""
    folder = tmp / name
    folder.mkdir(exist_ok=True)
    (folder / "m.yaml").write_text(_USING.replace("USE", "l0.yaml"))
    for i in range(depth):
        states = "".join(f"    u{k}:\n      use: l{i + 1}.yaml\n      transitions: [{{to: "
                         f"{f'u{k + 1}' if k + 1 < fan_out else 'ok'}, done: true}}]\n" for k in range(fan_out))
        (folder / f"l{i}.yaml").write_text(f"submission: l{i}\nmachine:\n  initial: u0\n  states:\n{states}"
                                           "    ok: {final: succeeded}\n")
    (folder / f"l{depth}.yaml").write_text("submission: leaf\nmachine:\n  initial: ok\n  states:\n"
                                           "    ok: {final: succeeded}\n")
    return folder / "m.yaml"


def _nested_states(tmp: Path, levels: int) -> Path:
    text = "mission: deep\nrobot: racecar\nworld: flat_ground\nrate_hz: 20\nmachine:\n  initial: s1\n  states:\n"
    ind = "    "
    for i in range(1, levels):
        text += f"{ind}s{i}:\n{ind}  initial: s{i + 1}\n{ind}  states:\n"
        ind += "    "
    path = tmp / "nested.yaml"
    path.write_text(text + f"{ind}s{levels}: {{final: true}}\n")
    return path


def _use_of(tmp: Path, name: str, target: str) -> Path:
    folder = tmp / name
    folder.mkdir(exist_ok=True)
    (folder / "m.yaml").write_text(_USING.replace("USE", target))
    return folder / "m.yaml"


def _seam_cases(tmp: Path) -> list[BadInput]:
    fan = _ladder(tmp, "fan_out", 7, 3)
    deep = _ladder(tmp, "use_depth", 10, 1)
    huge = _use_of(tmp, "huge_use", "lib/huge.yaml")
    (huge.parent / "lib").mkdir(exist_ok=True)
    with open(huge.parent / "lib" / "huge.yaml", "w") as f:
        f.write("submission: huge\nmachine: {initial: ok, states: {ok: {final: succeeded}}}\n")
        f.write("# padding\n" * 600_000)
    nested = _nested_states(tmp, 200)
    outside = _use_of(tmp, "outside", "../fan_out/l6.yaml")
    a_dir = _use_of(tmp, "a_dir", "lib")
    (a_dir.parent / "lib").mkdir(exist_ok=True)
    return [
        BadInput("use-fan-out", ("validate", str(fan)), "expand to more than 2000 states", f"{fan.parent / 'l'}"),
        BadInput("use-depth", ("validate", str(deep)), "sub-missions nest more than 8 deep", f"{deep.parent / 'l7.yaml'}:6:7"),
        BadInput("use-huge-file", ("validate", str(huge)), "larger than 5000000 bytes", f"{huge.parent / 'lib' / 'huge.yaml'}:1:1"),
        BadInput("states-200-deep", ("validate", str(nested)), "states nest more than 32 levels", f"{nested}:104:133"),
        BadInput("use-outside-folder", ("validate", str(outside)), "outside the mission's folder", f"{outside}:9:7"),
        BadInput("use-directory", ("validate", str(a_dir)), "is a directory", f"{a_dir}:9:7"),
        BadInput("sweep-not-key-values", ("batch", CAR, "--trials", "2", "--sweep", "rate_hz"), "is not KEY=V1,V2",
                 "taskflow batch: --sweep 'rate_hz'"),
        BadInput("sweep-empty-value", ("batch", CAR, "--trials", "2", "--sweep", "rate_hz=20,,40"), "an empty value",
                 "taskflow batch: --sweep 'rate_hz=20,,40'"),
        BadInput("sweep-bad-value", ("batch", CAR, "--trials", "2", "--sweep", "rate_hz=20,7"),
                 "does not divide the physics rate", f"{CAR}: --sweep rate_hz=7"),
        BadInput("sweep-not-a-mapping", ("batch", CAR, "--trials", "2", "--sweep", "rate_hz.x=1,2"), "is not a mapping",
                 f"{CAR}: --sweep rate_hz.x=1"),
        BadInput("set-unknown-state", ("validate", CAR, "--set", "machine.states.drivee.max_time=1"),
                 "no state 'drivee' in machine.states — did you mean 'drive'", f"{CAR}: --set machine.states.drivee"),
        BadInput("set-creates-a-key", ("validate", CAR, "--set", "machine.states.drive.taskk.params.x=1"),
                 "unknown key 'taskk'", f"{CAR}: --set machine.states.drive.taskk.params.x=1"),
        BadInput("set-bad-yaml", ("validate", CAR, "--set", "rate_hz=[20"), "value is not valid YAML",
                 f"{CAR}: --set rate_hz=[20"),
        BadInput("run-seed-negative", ("run", CAR, "--seed", "-3"), "a seed is a whole number from 0",
                 "taskflow run: --seed -3"),
        BadInput("run-seed-too-big", ("run", CAR, "--seed", str(2**63)), "a seed is a whole number from 0",
                 f"taskflow run: --seed {2**63}"),
        BadInput("batch-seed-negative", ("batch", CAR, "--trials", "2", "--seed", "-1"), "a seed is a whole number",
                 "taskflow batch: --seed -1"),
        BadInput("batch-seed-overflows", ("batch", CAR, "--trials", "3", "--seed", str(2**63 - 2)),
                 "trial i of 3 runs seed + i", f"taskflow batch: --seed {2**63 - 2}"),
        BadInput("teach-seed-negative", ("teach", QUAD, "--seed", "-1"), "a seed is a whole number",
                 "taskflow teach: --seed -1"),
        BadInput("check-steps-zero", ("check", "--world", "flat_ground", "--steps", "0"), "valid: 1 to 10000",
                 "taskflow check: --steps 0"),
        BadInput("check-param-typo", ("check", "--param", "flat_ground.frction=1"),
                 "unknown key 'frction' — did you mean 'friction'", "taskflow check: --param flat_ground.frction=1"),
        BadInput("check-param-bad-value", ("check", "--param", "flat_ground.friction=abc"), "valid number",
                 "taskflow check: --param flat_ground.friction=abc"),
        BadInput("check-param-unknown-world", ("check", "--param", "flat_grund.friction=1"),
                 "did you mean 'flat_ground'", "taskflow check: --param flat_grund.friction=1"),
        BadInput("view-port-out-of-range", ("view", str(tmp), "--port", "70000"), "valid: 0 to 65535",
                 "taskflow view: --port 70000"),
        BadInput("check-world-cannot-host", ("check", "--world", "flat_ground", "--robot", "quadcopter"),
                 "worlds that host it: quad_room", "taskflow check: --world flat_ground --robot quadcopter"),
    ]


def _bound_cases() -> list[BadInput]:
    """Values the robot or world cannot honour, and a guard its metric can never satisfy, given on the command
    line: each refused at the ``--set`` with the reason."""
    return [
        BadInput("bound-racecar-v-max", ("validate", CAR, "--set", "robot.params.v_max=1000"),
                 "less than or equal to 2.5", f"{CAR}: --set robot.params.v_max=1000"),
        BadInput("bound-screw-rate", ("validate", SCREW, "--set", "rate_hz=1"), "too slow for world 'screw_conveyor'",
                 f"{SCREW}: --set rate_hz=1"),
        BadInput("bound-guard-negative-distance", ("validate", SCREW, "--set", "parameters.eps_t=-1 mm"),
                 "can never hold", f"{SCREW}: --set parameters.eps_t=-1 mm"),
        BadInput("bound-viki-camera-rate", ("validate", VIKI, "--set", "world.params.camera_rate_hz=60"),
                 "camera rate above the control rate_hz", f"{VIKI}: --set world.params.camera_rate_hz=60"),
        BadInput("bound-viki-pixel-noise", ("validate", VIKI, "--set", "world.params.pixel_noise=1e6"),
                 "less than or equal to 20", f"{VIKI}: --set world.params.pixel_noise=1e6"),
    ]
