"""The control endpoint of a running mission (HTTP + JSON, for ``taskflow ctl`` and a browser) and its client.

``GET /state``    ``{mission, state, t, tick, paused, held, outcome, reason, running}``
``GET /mission``  ``{mission, actions, states, events}``: what may be asked of this run
``POST /pause``, ``/hold``, ``/resume``, ``/preempt`` ``{to?}``, ``/inject`` ``{event}`` — every body may give
                  ``who``; the answer is ``{"queued": ACTION, "who": WHO}``: the action takes effect at the
                  next tick boundary (:mod:`taskflow.control`).  A bad request is HTTP 400 ``{"error": MESSAGE}``.

The server is starlette on uvicorn, run in a daemon thread (uvicorn installs no signal handler off the
main thread, so the run loop's Ctrl-C / SIGTERM handling stays as it is).  It binds ``127.0.0.1`` unless
told otherwise; port 0 picks a free port, and the address is written to ``RUN_DIR/control.json`` (removed
when the run ends) so that ``taskflow ctl RUN_DIR ACTION`` finds it.
"""

from __future__ import annotations

import json
import socket
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from .control import ACTIONS, ControlError, OperatorAction, OperatorChannel

if TYPE_CHECKING:
    from .view import RunView

DEFAULT_ADDRESS = "127.0.0.1:0"
VIEW_LINGER_S = 1.0  # wall seconds a live view's server stays up after the run (the page polls every 0.4 s)
CONTROL_FILE = "control.json"


def parse_address(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (``PORT`` 0: any free port) → ``(host, port)``."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or int(port) > 65535:
        raise ControlError(f"{text!r} is not HOST:PORT (e.g. 127.0.0.1:8765, or port 0 for any free port)")
    return host.strip("[]"), int(port)


LOOPBACK = ("127.0.0.1", "localhost", "::1")


def _app(channel: OperatorChannel | None, host: str, view: "RunView | None" = None) -> Any:
    """The routes (with ``view``, the web view's too: :mod:`taskflow.view_http`; without ``channel``, a
    replay: ``/state`` tells the run's end and the actions answer 409).  On a loopback address only
    requests naming a loopback host are served (no DNS rebinding), and a POST must say ``Content-Type: application/json`` (a page of another origin cannot
    send that without a CORS preflight, which is never granted): no web page can drive the robot by
    accident."""
    from starlette.applications import Starlette
    from starlette.middleware import Middleware
    from starlette.middleware.trustedhost import TrustedHostMiddleware
    from starlette.requests import Request
    from starlette.responses import JSONResponse
    from starlette.routing import Route

    async def state(request: Request) -> JSONResponse:
        return JSONResponse(channel.snapshot() if channel is not None else view.replay_state())  # type: ignore[union-attr]

    async def mission(request: Request) -> JSONResponse:
        if channel is None:
            return JSONResponse({"mission": view.mission.name, "actions": [], "states": [], "events": []})  # type: ignore[union-attr]
        return JSONResponse(channel.describe())

    async def act(request: Request) -> JSONResponse:
        name = request.path_params["action"]
        if name not in ACTIONS:
            return JSONResponse({"error": f"no action {name!r}; valid: {', '.join(ACTIONS)}"}, status_code=404)
        if channel is None:
            return JSONResponse({"error": f"{name}: this is a replay of a finished run"}, status_code=409)
        if request.headers.get("content-type", "").split(";")[0].strip() != "application/json":
            return JSONResponse({"error": "send the body as Content-Type: application/json"}, status_code=415)
        raw = await request.body()
        try:
            body = json.loads(raw) if raw.strip() else {}
        except ValueError:
            return JSONResponse({"error": "the body is not JSON"}, status_code=400)
        if not isinstance(body, dict):
            return JSONResponse({"error": "the body must be a JSON object"}, status_code=400)
        who = body.pop("who", "operator")
        try:
            action = OperatorAction.model_validate({"action": name, "who": who, "args": body})
            channel.submit(action)
        except ControlError as exc:
            return JSONResponse({"error": str(exc)}, status_code=400)
        except ValueError as exc:  # pydantic's ValidationError
            msgs = "; ".join(e["msg"].removeprefix("Value error, ") for e in exc.errors())  # type: ignore[attr-defined]
            return JSONResponse({"error": f"{name}: {msgs}"}, status_code=400)
        return JSONResponse({"queued": name, "who": action.who})

    hosts = ["127.0.0.1", "localhost", "[::1]"] if host in LOOPBACK else ["*"]
    routes = [Route("/state", state), Route("/mission", mission), Route("/{action}", act, methods=["POST"])]
    if view is not None:
        from .view_http import view_routes

        routes = view_routes(view) + routes
    return Starlette(routes=routes,
                     middleware=[Middleware(TrustedHostMiddleware, allowed_hosts=hosts)])


class ControlServer:
    """The endpoint of one run.  The socket is bound on construction (a port in use fails here, in the
    caller's thread); :meth:`start` serves ``channel`` from a daemon thread and calls ``announce(url,
    run_dir)``, :meth:`stop` ends it.  With ``view=True`` it also serves the web view of the run it
    records (``taskflow run --view``, :mod:`taskflow.view`)."""

    def __init__(self, address: str = DEFAULT_ADDRESS,
                 announce: Callable[[str, Path | None], None] | None = None, view: bool = False) -> None:
        host, port = parse_address(address)
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self.socket = socket.socket(family, socket.SOCK_STREAM)
        try:
            self.socket.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self.socket.bind((host, port))
            self.socket.listen(16)  # from now on requests wait in the backlog until start()
        except OSError as exc:
            self.socket.close()
            raise ControlError(f"cannot listen on {address}: {exc.strerror or exc}") from None
        bound = self.socket.getsockname()
        self.url = f"http://{host if family == socket.AF_INET else f'[{host}]'}:{bound[1]}"
        self.host = host
        self.announce = announce
        self.view = view
        self._server: Any = None
        self._thread: threading.Thread | None = None
        self._control_file: Path | None = None

    def start(self, channel: OperatorChannel | None, run_dir: Path | None, view: "RunView | None" = None) -> None:
        """Serve ``channel`` (None: a replay) and, given ``view``, the web page of the run."""
        import uvicorn

        if view is None and self.view and channel is not None and run_dir is not None:
            from .view import RunView

            view = RunView(channel.mission, run_dir, live=True)
        config = uvicorn.Config(_app(channel, self.host, view), log_level="warning", lifespan="off", access_log=False,
                                timeout_graceful_shutdown=1)
        self._server = uvicorn.Server(config)
        self._thread = threading.Thread(target=self._server.run, kwargs={"sockets": [self.socket]},
                                        name="taskflow-control", daemon=True)
        self._thread.start()
        if run_dir is not None and channel is not None:
            self._control_file = run_dir / CONTROL_FILE
            tmp = self._control_file.with_suffix(".tmp")
            tmp.write_text(json.dumps({"url": self.url, "mission": channel.mission.name}) + "\n")
            tmp.replace(self._control_file)
        if self.announce is not None:
            self.announce(self.url, run_dir)

    def stop(self) -> None:
        if self._control_file is not None:
            self._control_file.unlink(missing_ok=True)
        if self.view and self._server is not None:
            time.sleep(VIEW_LINGER_S)  # a page following the run polls once more and gets the record's end
        if self._server is not None:
            self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self.socket.close()


class ControlClient:
    """Talks to a run's endpoint; every failure is a :class:`ControlError` with the server's message."""

    def __init__(self, url: str, timeout: float = 10.0) -> None:
        self.url = url.rstrip("/")
        self.timeout = timeout

    @classmethod
    def for_run(cls, run_dir: str | Path) -> "ControlClient":
        """The client of the run writing ``run_dir`` (its ``control.json``)."""
        path = Path(run_dir) / CONTROL_FILE
        try:
            url = json.loads(path.read_text())["url"]
        except FileNotFoundError:
            what = "no such folder" if not Path(run_dir).is_dir() else (
                f"it has no {CONTROL_FILE}: the run has ended, or was started with --no-control")
            raise ControlError(f"{run_dir}: {what}") from None
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ControlError(f"{path}: unreadable ({exc})") from None
        return cls(url)

    def state(self) -> dict[str, Any]:
        return self._call("GET", "/state")

    def mission(self) -> dict[str, Any]:
        return self._call("GET", "/mission")

    def send(self, action: str, who: str = "operator", **args: str) -> dict[str, Any]:
        """POST one action (``to=`` of a pre-emption, ``event=`` of an injection)."""
        return self._call("POST", f"/{action}", {"who": who, **args})

    def _call(self, method: str, path: str, body: dict[str, Any] | None = None) -> dict[str, Any]:
        data = json.dumps(body).encode() if body is not None else None
        req = urllib.request.Request(self.url + path, data=data, method=method,
                                     headers={"Content-Type": "application/json"})
        try:
            with urllib.request.urlopen(req, timeout=self.timeout) as resp:
                return dict(json.loads(resp.read()))
        except urllib.error.HTTPError as exc:
            try:
                message = json.loads(exc.read())["error"]
            except (ValueError, KeyError, TypeError):
                message = f"HTTP {exc.code} {exc.reason}"
            raise ControlError(message) from None
        except (urllib.error.URLError, OSError) as exc:
            reason = getattr(exc, "reason", exc)
            raise ControlError(f"no run answers at {self.url} ({reason}): has it ended?") from None
