"""Wall time and peak memory of every broken command-line input of ``tests/bad_inputs.py``, each run as
``taskflow …`` in a fresh process (the budget: one line, exit 1, within 1 s and 200 MB).

Run: ``python benchmarks/bad_input.py`` — one line per case, then a JSON line with the worst time and
memory.  Times include starting Python and importing numpy, pydantic and the world's module; ``cpu`` is the
process's own user + system time (what a busy machine inflates least).  A case is ``ok`` when it exits 1
with one line, no traceback, its fragment, and the line starts with its ``where`` (FILE:LINE:COL, the
``--set``/``--sweep`` or the option).
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from bad_inputs import cases


def main() -> None:
    tmp = Path(tempfile.mkdtemp(prefix="taskflow-bad-input-"))
    rows = []
    for case in cases(tmp):
        t0 = time.perf_counter()
        pid = os.posix_spawn(sys.executable, [sys.executable, "-c",
                                              "from taskflow.cli import main; raise SystemExit(main())", *case.argv],
                             os.environ, file_actions=[(os.POSIX_SPAWN_OPEN, 1, os.devnull, os.O_WRONLY, 0),
                                                       (os.POSIX_SPAWN_OPEN, 2, str(tmp / "err.txt"),
                                                        os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)])
        _, status, usage = os.wait4(pid, 0)
        wall = time.perf_counter() - t0
        code = os.waitstatus_to_exitcode(status)
        err = (tmp / "err.txt").read_text()
        lines = err.splitlines()
        ok = code == 1 and len(lines) == 1 and case.fragment in err and "Traceback" not in err
        mb = usage.ru_maxrss / 1024.0
        cpu = usage.ru_utime + usage.ru_stime  # what the process itself used: less sensitive to a busy machine
        ok = ok and lines[0].startswith(case.where)  # ok already means exactly one line
        rows.append({"case": case.name, "exit": code, "one_line": len(lines) == 1, "ok": ok, "wall_s": round(wall, 3),
                     "cpu_s": round(cpu, 3), "peak_rss_mb": round(mb, 1)})
        print(f"{case.name:30s} exit {code}  {'ok ' if ok else 'BAD'}  {wall:5.2f} s  cpu {cpu:5.2f} s  {mb:6.1f} MB  "
              f"{lines[0][:80] if lines else ''}", flush=True)
    print(json.dumps({"cases": len(rows), "all_ok": all(r["ok"] for r in rows),
                      "max_wall_s": max(r["wall_s"] for r in rows), "max_cpu_s": max(r["cpu_s"] for r in rows),
                      "max_peak_rss_mb": max(r["peak_rss_mb"] for r in rows), "rows": rows}))


if __name__ == "__main__":
    main()
