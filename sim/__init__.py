"""The PyBullet "hardware": worlds, robot bodies and sensors (the only package importing pybullet).

PyBullet's C module prints a "pybullet build time" banner on stderr when it is imported; it would
precede every ``taskflow validate`` answer and every test run's output.  It is imported here once
with the process's stderr pointed at the null device, so every ``sim`` module gets it silently
(an import error still raises, as a Python exception).
"""

from __future__ import annotations

import ctypes
import os
import sys


def _import_pybullet_quietly() -> None:
    if "pybullet" in sys.modules:
        return
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no usable fd 2: import as is
        import pybullet
        return
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
            import pybullet  # noqa: F401

            ctypes.CDLL(None).fflush(None)  # in case C's stdio buffered it
    finally:
        os.dup2(saved, 2)
        os.close(saved)


_import_pybullet_quietly()
