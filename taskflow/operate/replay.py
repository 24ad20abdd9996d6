"""``taskflow view RUN_DIR``: a finished run served by the control app (:mod:`taskflow.operate.control_http`)
with the web view's routes (:mod:`taskflow.operate.view_http`), without a run loop."""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from taskflow.operate.control_http import ControlServer
from taskflow.operate.view import open_run


def serve_replay(run_dir: str | Path, address: str,
                 announce: Callable[[str, Path | None, str | None], None] | None = None) -> Any:
    """Start serving the finished run ``run_dir`` on ``address`` (``HOST:PORT``) from a daemon thread and
    return its :class:`~taskflow.operate.control_http.ControlServer` (``.url``; ``.token``: None on loopback, else
    the secret every request must carry; ``.stop()``).  Raises
    :class:`~taskflow.operate.view.ViewError` or :class:`~taskflow.execution.control.ControlError` with the reason."""
    view = open_run(run_dir)
    server = ControlServer(address, announce)
    server.start(None, None, view=view)
    return server


def wait_forever(server: Any) -> None:
    """Block until Ctrl-C (``taskflow view``: the way to end it, not an error), then stop ``server``."""
    try:
        threading.Event().wait()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
