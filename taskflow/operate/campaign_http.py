"""The campaign page's routes (``taskflow view BATCH_DIR``), served by the control app's server
(:class:`taskflow.operate.control_http.ControlServer`) behind its guards, without a run loop.

``GET /``                the page (``web/campaign.html``);  ``GET /web/FILE`` its script and style
``GET /campaign``        :meth:`taskflow.operate.campaign_view.CampaignView.page`
``/run/FOLDER/…``        a kept trial's replay: the run view's page and routes (:mod:`taskflow.operate.view_http`)
                         of ``BATCH_DIR/FOLDER``, opened (:func:`taskflow.operate.view.open_run`) on its first
                         request; a record that cannot be opened answers 422 ``{error}`` (one line)

Only the folders the page links to are served: those of ``batch.json``'s trials that were kept.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from taskflow.operate.campaign_view import RUN_PREFIX, CampaignView
from taskflow.operate.control_http import control_app
from taskflow.operate.view import WEB_DIR, ViewError, open_run


class _KeptRun:
    """ASGI app of one kept trial's replay, opened on its first request (a campaign of many trials
    compiles only the missions of the replays looked at)."""

    def __init__(self, run_dir: Path, host: str) -> None:
        self.run_dir = run_dir
        self.host = host
        self._app: Any = None
        self._error = ""

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        from starlette.responses import JSONResponse

        if self._app is None and not self._error:
            try:
                self._app = control_app(None, self.host, open_run(self.run_dir))
            except ViewError as exc:
                self._error = str(exc)
        if self._app is None:
            await JSONResponse({"error": self._error}, status_code=422)(scope, receive, send)
            return
        await self._app(scope, receive, send)


def campaign_routes(view: CampaignView, host: str) -> list[Any]:
    """The page, its files, its JSON and a mount per kept trial's replay (module docstring)."""
    from starlette.requests import Request
    from starlette.responses import FileResponse, JSONResponse
    from starlette.routing import Mount, Route
    from starlette.staticfiles import StaticFiles

    async def page(request: Request) -> FileResponse:
        return FileResponse(WEB_DIR / "campaign.html", headers={"Cache-Control": "no-store"})

    async def campaign(request: Request) -> JSONResponse:
        return JSONResponse(view.page())

    runs = [Mount(f"/{RUN_PREFIX}/{rel}", app=_KeptRun(path, host)) for rel, path in view.runs.items()]
    return [Route("/", page), Route("/campaign", campaign), *runs,
            Mount("/web", app=StaticFiles(directory=WEB_DIR), name="web")]
