"""The web view's routes, added to the control app (:mod:`taskflow.operate.control_http`), and ``taskflow view``.

A live run (``taskflow run --view``) serves them from its control endpoint; ``taskflow view RUN_DIR``
serves a finished run with the same app, without a run loop (``GET /state`` then tells the run's end, and
the operator POSTs answer 409).  :mod:`taskflow.operate.view` says what each route returns.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from taskflow.operate.view import WEB_DIR, RunView, open_run
from taskflow.readers.record_io import RunDirError


def _refusing_bad_records(endpoint: Callable[[Any], Any]) -> Callable[[Any], Any]:
    """``endpoint``, answering a malformed or hostile record (:class:`~taskflow.readers.record_io.RunDirError`:
    a file outside the run folder, a line too long, a field of the wrong type) with 422 ``{error}`` —
    one line naming the file and line — instead of serving it."""
    from starlette.responses import JSONResponse

    async def guarded(request: Any) -> Any:
        try:
            return await endpoint(request)
        except RunDirError as exc:
            return JSONResponse({"error": str(exc)}, status_code=422)

    return guarded


def view_routes(view: RunView) -> list[Any]:
    """The page, its files and the JSON the page polls (a bad record: 422, :func:`_refusing_bad_records`)."""
    from starlette.requests import Request
    from starlette.responses import FileResponse, JSONResponse, Response
    from starlette.routing import Mount, Route
    from starlette.staticfiles import StaticFiles

    def since(request: Request) -> int:
        try:
            return max(0, int(request.query_params.get("since", "0")))
        except ValueError:
            return 0

    async def page(request: Request) -> FileResponse:
        return FileResponse(WEB_DIR / "index.html", headers={"Cache-Control": "no-store"})

    async def machine(request: Request) -> JSONResponse:
        return JSONResponse(view.machine())

    async def trace(request: Request) -> JSONResponse:
        return JSONResponse(view.reader.trace(since(request)))

    async def transitions(request: Request) -> JSONResponse:
        return JSONResponse(view.reader.transitions(since(request)))

    async def summary(request: Request) -> JSONResponse:
        return JSONResponse(view.reader.summary())

    async def frames(request: Request) -> JSONResponse:
        return JSONResponse(view.reader.frame_records(since(request)))

    async def frame(request: Request) -> Response:
        sensor = request.query_params.get("sensor", "")
        text = request.query_params.get("t")
        try:
            t = None if text is None else float(text)
            if t is not None and not math.isfinite(t):
                raise ValueError(text)
        except ValueError:
            return JSONResponse({"error": f"t={text!r}: a sim time in seconds"}, status_code=400)
        found = view.reader.frame(sensor, t)
        if found is None:
            known = sorted({f.sensor for f in view.reader.frames})
            return JSONResponse({"error": f"no frame of camera {sensor!r} in this run — recorded: "
                                          f"{', '.join(known) or 'none'}"}, status_code=404)
        rec, data = found
        return Response(data, media_type=f"image/{Path(rec.file).suffix[1:]}",
                        headers={"X-Frame-Stamp": repr(rec.stamp), "X-Frame-T": repr(rec.t),
                                 "Cache-Control": "no-store", "X-Content-Type-Options": "nosniff"})

    guard = _refusing_bad_records
    return [Route("/", page), Route("/view/machine", guard(machine)), Route("/view/trace", guard(trace)),
            Route("/view/transitions", guard(transitions)), Route("/view/summary", guard(summary)),
            Route("/view/frames", guard(frames)), Route("/view/frame", guard(frame)),
            Mount("/web", app=StaticFiles(directory=WEB_DIR), name="web")]


def serve_replay(run_dir: str | Path, address: str,
                 announce: Callable[[str, Path | None, str | None], None] | None = None) -> Any:
    """Start serving the finished run ``run_dir`` on ``address`` (``HOST:PORT``) from a daemon thread and
    return its :class:`~taskflow.operate.control_http.ControlServer` (``.url``; ``.token``: None on loopback, else
    the secret every request must carry; ``.stop()``).  Raises
    :class:`~taskflow.operate.view.ViewError` or :class:`~taskflow.operate.control.ControlError` with the reason."""
    from taskflow.operate.control_http import ControlServer

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
