"""``taskflow view DIR``: a finished run, or a campaign's page, served by the control app
(:mod:`taskflow.operate.control_http`) without a run loop — a run with the web view's routes
(:mod:`taskflow.operate.view_http`), a batch folder with the campaign page's (:mod:`taskflow.operate.campaign_http`),
which serves its kept trials' replays too."""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from taskflow.operate.campaign_view import is_campaign, open_campaign
from taskflow.operate.control_http import ControlServer
from taskflow.operate.view import ViewError, open_run


def serve_replay(run_dir: str | Path, address: str,
                 announce: Callable[[str, Path | None, str | None], None] | None = None) -> Any:
    """Start serving the finished run — or the batch folder (:func:`serve_campaign`) — ``run_dir`` on
    ``address`` (``HOST:PORT``) from a daemon thread and return its
    :class:`~taskflow.operate.control_http.ControlServer` (``.url``; ``.token``: None on loopback, else
    the secret every request must carry; ``.stop()``).  Raises
    :class:`~taskflow.operate.view.ViewError` or :class:`~taskflow.execution.control.ControlError` with the reason."""
    if is_campaign(run_dir):
        return serve_campaign(run_dir, address, announce)
    d = Path(run_dir)
    if d.is_dir() and not (d / "trace.csv").is_file():
        raise ViewError(f"{d}: neither a run folder (it has no trace.csv) nor a batch folder (no batch.json)")
    view = open_run(run_dir)
    server = ControlServer(address, announce)
    server.start(None, None, view=view)
    return server


def serve_campaign(batch_dir: str | Path, address: str,
                   announce: Callable[[str, Path | None, str | None], None] | None = None) -> Any:
    """Start serving the campaign page of ``batch_dir`` (and its kept trials' replays) as :func:`serve_replay`
    serves a run."""
    from taskflow.operate.campaign_http import campaign_routes

    view = open_campaign(batch_dir)
    server = ControlServer(address, announce)
    server.start(None, None, routes=campaign_routes(view, server.host))
    return server


def wait_forever(server: Any) -> None:
    """Block until Ctrl-C (``taskflow view``: the way to end it, not an error), then stop ``server``."""
    try:
        threading.Event().wait()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
