"""``taskflow batch`` says how far it is while it runs (on stderr): on a terminal one line rewritten in
place, otherwise one line per finished trial; ``batch.json`` stays byte for byte what a silent batch writes.
Real ``taskflow batch`` processes on the toy mission (registered by the child's own ``import toys``)."""

from __future__ import annotations

import io
import os
import pty
import re
import select
import subprocess
import sys
from pathlib import Path

from taskflow.campaigns.batch import BatchProgress, resume_batch, run_batch

HERE = Path(__file__).resolve().parents[1]
TOY = HERE / "machine" / "missions" / "toy_full.yaml"
# two conditions of two trials: the tool works (succeeded) or fails (failed), so 2 of 4 succeed
ARGS = ["batch", str(TOY), "--trials", "2", "--workers", "1", "--seed", "3", "--sweep", "world.params.tool_ok=true,false"]
CHILD = (f"import sys; sys.path.insert(0, {str(HERE)!r}); import toys; toys.register(); "
         "from taskflow.cli import main; raise SystemExit(main(sys.argv[1:]))")


def _silent_batch_json(tmp_path: Path) -> bytes:
    """batch.json of the same campaign run through the library with no progress reporter."""
    run_batch(str(TOY), trials=2, workers=1, seed=3, sweep=["world.params.tool_ok=true,false"], out=tmp_path / "silent")
    return (tmp_path / "silent" / "batch.json").read_bytes()


def test_a_batch_writes_one_line_per_finished_trial_to_a_pipe(tmp_path: Path) -> None:
    out = tmp_path / "piped"
    proc = subprocess.run([sys.executable, "-c", CHILD, *ARGS, "--out", str(out)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 1, proc.stderr  # 2 of 4 failed
    lines = [line for line in proc.stderr.splitlines() if line.startswith("batch toy_full: ")]
    assert "\r" not in proc.stderr and "\x1b[" not in proc.stderr
    assert len(lines) == 4, proc.stderr
    for k, line in enumerate(lines, 1):
        assert re.fullmatch(rf"batch toy_full: {k}/4 trials, \d succeeded(, ETA \d+ s)? "
                            r"\(condition [01] seed [34]: (succeeded|failed)\)", line), line
        assert ("ETA" in line) == (k < 4)
    assert [re.search(r"(\d) succeeded,?", line).group(1) for line in lines] == ["1", "2", "2", "2"]  # type: ignore[union-attr]
    assert lines[-1].endswith("(condition 1 seed 4: failed)")
    assert "batch toy_full" not in proc.stdout  # the table alone on stdout
    assert (out / "batch.json").read_bytes() == _silent_batch_json(tmp_path)


def test_a_batch_on_a_terminal_rewrites_one_progress_line(tmp_path: Path) -> None:
    out = tmp_path / "tty"
    master, slave = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-c", CHILD, *ARGS, "--out", str(out)], stdout=subprocess.PIPE,
                            stderr=slave, text=True)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 65536)
        except OSError:  # EIO: the child closed the terminal
            break
        if not data:
            break
        chunks.append(data)
    os.close(master)
    stdout, _ = proc.communicate(timeout=120)
    assert proc.returncode == 1
    err = b"".join(chunks).decode().replace("\r\n", "\n")  # the terminal turns "\n" into "\r\n"
    progress = err[err.index("\rbatch toy_full: "):]
    assert progress.count("\n") == 1 and progress.endswith("\n")  # one line, ended once the batch is done
    states = [s.removesuffix("\x1b[K\n").removesuffix("\x1b[K") for s in progress.split("\r") if s]
    assert states[0] == "batch toy_full: 0/4 trials, 0 succeeded, running …"
    assert [re.match(r"batch toy_full: (\d/4 trials, \d succeeded)", s).group(1) for s in states[1:]] == [  # type: ignore[union-attr]
        "1/4 trials, 1 succeeded", "2/4 trials, 2 succeeded", "3/4 trials, 2 succeeded", "4/4 trials, 2 succeeded"]
    assert all(re.search(r", ETA \d+ s$", s) for s in states[1:4]) and "ETA" not in states[4]
    assert "success 2/4" in stdout
    assert (out / "batch.json").read_bytes() == _silent_batch_json(tmp_path)


def test_a_resumed_batch_counts_the_trials_already_recorded(tmp_path: Path) -> None:
    out = tmp_path / "b"
    run_batch(str(TOY), trials=3, workers=1, seed=3, out=out)
    (out / "trials" / "c000-s00004.json").unlink()  # as if the batch had been stopped before seed 4 finished
    log = io.StringIO()
    resume_batch(out, workers=1, progress=BatchProgress(log, tty=False))
    assert log.getvalue() == "batch toy_full: 3/3 trials, 3 succeeded (condition 0 seed 4: succeeded)\n"


def test_the_terminal_line_is_cut_to_the_terminal_width() -> None:
    import fcntl
    import struct
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 30, 0, 0))  # a 30-column terminal
    with os.fdopen(slave, "w") as term:
        progress = BatchProgress(term)
        assert progress.tty
        progress.start("a_mission_with_a_long_name", 10, 0, 0)
        progress.trial(0, 1, "succeeded")
        progress.finish()
    raw = b""
    while select.select([master], [], [], 0.5)[0]:
        try:
            raw += os.read(master, 4096)
        except OSError:
            break
    os.close(master)
    shown = raw.decode().replace("\r\n", "\n")
    assert shown.endswith("\n") and shown.count("\n") == 1
    lines = [s.rstrip("\n").removesuffix("\x1b[K") for s in shown.split("\r") if s.strip()]
    assert lines == ["batch a_mission_with_a_long_…"] * 2  # 29 columns: \r rewrites it, nothing wraps
