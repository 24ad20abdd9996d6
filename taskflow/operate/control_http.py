"""The control endpoint of a running mission (HTTP + JSON, for ``taskflow ctl`` and a browser) and its client.

``GET /state``    ``{mission, state, t, tick, paused, held, outcome, reason, running}``
``GET /mission``  ``{mission, actions, states, events}``: what may be asked of this run
``POST /pause``, ``/hold``, ``/resume``, ``/preempt`` ``{to?}``, ``/inject`` ``{event}`` — every body may give
                  ``who``; the answer is ``{"queued": ACTION, "who": WHO}``: the action takes effect at the
                  next tick boundary (:mod:`taskflow.execution.control`).  A bad request is HTTP 400 ``{"error": MESSAGE}``.

The server is starlette on uvicorn, run in a daemon thread (uvicorn installs no signal handler off the
main thread, so the run loop's Ctrl-C / SIGTERM handling stays as it is).  It binds ``127.0.0.1`` unless
told otherwise; port 0 picks a free port, and the address is written to ``RUN_DIR/control.json`` (removed
when the run ends) so that ``taskflow ctl RUN_DIR ACTION`` finds it.

Who may drive the robot: each server draws a secret token (``secrets.token_hex(32)``: 256 bits as 64 hex digits, so it never starts
with ``-`` and ``taskflow ctl --token TOKEN`` always parses), written in
``control.json`` (created mode 0600: readable by the run's owner only) and printed once with the page's
address (``http://HOST:PORT/?token=…``).  Every POST must carry it (``Authorization: Bearer TOKEN``, or
``?token=``), and so must every GET when the server listens on an address other than loopback (the page's
own static files under ``/web/`` excepted: they are the package's, the same for every run).  Without it the
answer is 401, with a wrong one 403 (compared with :func:`hmac.compare_digest`); a refused request changes
nothing and is logged — a line on stderr and one in ``RUN_DIR/refused.jsonl`` (:class:`TokenGate`).  A
replay (``taskflow view``) on loopback drives nothing and needs no token; off loopback it needs one.

``control.json`` also names the run's process (``pid`` and its start time), so that ``taskflow ctl`` tells
a run that died without removing it (``kill -9``) from one that is running (:meth:`ControlClient.for_run`).
"""

from __future__ import annotations

import hmac
import ipaddress
import json
import os
import secrets
import socket
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import ValidationError

from taskflow.execution.control import ACTIONS, ControlError, OperatorAction, OperatorChannel

if TYPE_CHECKING:
    from taskflow.operate.view import RunView

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
REFUSED_FILE = "refused.jsonl"
MAX_REFUSED_LOGGED = 1000  # refusals logged per server; a flood of them does not fill the disk


def is_loopback(host: str) -> bool:
    """``host`` (as given to ``--control`` / ``--host``) names this machine's loopback interface only."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False



def new_token() -> str:
    """A run's secret: 256 random bits as 64 hex digits (never a leading ``-``, which ``--token`` would take
    for an option: ``secrets.token_urlsafe`` drew one in 64 runs)."""
    return secrets.token_hex(32)

class TokenGate:
    """ASGI middleware: refuse a request that lacks the run's token (401) or carries another (403).

    ``token`` None: nothing is gated.  A POST always needs it; a GET only when ``reads`` (a server bound to
    an address other than loopback), and never for the package's static files under ``/web/``.  The token is
    ``Authorization: Bearer TOKEN`` or the query parameter ``token`` (an ``<img>`` cannot send a header).
    Each refusal is passed to ``on_refused(method, path, client, status, why)``."""

    def __init__(self, app: Any, token: str | None, reads: bool,
                 on_refused: Callable[[str, str, str, int, str], None]) -> None:
        self.app = app
        self.token = token
        self.reads = reads
        self.on_refused = on_refused

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        from starlette.requests import Request
        from starlette.responses import JSONResponse

        if scope["type"] != "http" or self.token is None:
            await self.app(scope, receive, send)
            return
        request = Request(scope)
        if request.method in ("GET", "HEAD") and (not self.reads or request.url.path.startswith("/web/")):
            await self.app(scope, receive, send)
            return
        given = request.query_params.get("token", "")
        scheme, _, value = request.headers.get("authorization", "").partition(" ")
        if scheme.lower() == "bearer" and value.strip():
            given = value.strip()
        if not given:
            status, why = 401, "no token"
            error = ("this run's endpoint needs its token — send Authorization: Bearer TOKEN (taskflow ctl reads it "
                     "from RUN_DIR/control.json; the page takes it from the address it was printed with, ?token=)")
        elif not hmac.compare_digest(given.encode(), self.token.encode()):
            status, why, error = 403, "wrong token", "wrong token for this run — the run's token is in RUN_DIR/control.json"
        else:
            await self.app(scope, receive, send)
            return
        client = f"{request.client.host}:{request.client.port}" if request.client else "?"
        self.on_refused(request.method, request.url.path, client, status, why)
        headers = {"WWW-Authenticate": "Bearer"} if status == 401 else None
        await JSONResponse({"error": error}, status_code=status, headers=headers)(scope, receive, send)


def process_start(pid: int) -> str | None:
    """When process ``pid`` started (Linux: ticks since boot, ``/proc/PID/stat`` field 22), None if unknown:
    with the pid it names one process, not a later one that got the same number."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = stat.rpartition(")")[2].split()  # after the command name, which may hold spaces
    return fields[19] if len(fields) > 19 else None


def process_alive(pid: int, start: str | None) -> bool:
    """Process ``pid`` exists, is not a zombie, and (given ``start``) is the one that started then."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass  # another user's process: it exists
    except OSError:
        return False
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()
    except OSError:
        return True  # no /proc (not Linux): the signal test is all there is
    if fields and fields[0] in ("Z", "X"):
        return False
    return start is None or len(fields) <= 19 or fields[19] == start


def write_private(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` readable by its owner only: the file is created with mode 0600 (no moment
    where another user could read it), then moved into place."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.unlink(missing_ok=True)
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(text)
    tmp.replace(path)


def control_app(channel: OperatorChannel | None, host: str, view: RunView | None = None, token: str | None = None,
         on_refused: Callable[[str, str, str, int, str], None] | None = None) -> Any:
    """The routes (with ``view``, the web view's too: :mod:`taskflow.operate.view_http`; without ``channel``, a
    replay: ``/state`` tells the run's end and the actions answer 409).  On a loopback address only
    requests naming a loopback host are served (no DNS rebinding), and a POST must say ``Content-Type: application/json`` (a page of another origin cannot
    send that without a CORS preflight, which is never granted): no web page can drive the robot by
    accident.  Given ``token``, :class:`TokenGate` decides who may ask at all."""
    from starlette.requests import Request
    from starlette.responses import JSONResponse
    from starlette.routing import Route

    async def state(request: Request) -> JSONResponse:
        if channel is not None:
            return JSONResponse(channel.snapshot())
        assert view is not None, "a replay serves its view"
        return JSONResponse(view.replay_state())

    async def mission(request: Request) -> JSONResponse:
        if channel is None:
            assert view is not None, "a replay serves its view"
            return JSONResponse({"mission": view.mission.name, "actions": [], "states": [], "events": []})
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
        except ValidationError as exc:
            msgs = "; ".join(e["msg"].removeprefix("Value error, ") for e in exc.errors())
            return JSONResponse({"error": f"{name}: {msgs}"}, status_code=400)
        note = channel.note(action)
        return JSONResponse({"queued": name, "who": action.who, **({"note": note} if note else {})})

    routes = [Route("/state", state), Route("/mission", mission), Route("/{action}", act, methods=["POST"])]
    if view is not None:
        from taskflow.operate.view_http import view_routes

        routes = view_routes(view) + routes
    return guarded_app(routes, host, token, on_refused)


def guarded_app(routes: list[Any], host: str, token: str | None = None,
                on_refused: Callable[[str, str, str, int, str], None] | None = None) -> Any:
    """``routes`` as a starlette app behind the endpoint's guards (:func:`control_app`): loopback hosts only on a
    loopback address, and :class:`TokenGate` given ``token``.  The campaign page is served so too."""
    from starlette.applications import Starlette
    from starlette.middleware import Middleware
    from starlette.middleware.trustedhost import TrustedHostMiddleware

    hosts = ["127.0.0.1", "localhost", "[::1]"] if host in LOOPBACK else ["*"]
    return Starlette(routes=routes,
                     middleware=[Middleware(TrustedHostMiddleware, allowed_hosts=hosts),
                                 Middleware(TokenGate, token=token, reads=not is_loopback(host),
                                            on_refused=on_refused or (lambda *a: None))])


class ControlServer:
    """The endpoint of one run.  The socket is bound on construction (a port in use fails here, in the
    caller's thread); :meth:`start` serves ``channel`` from a daemon thread and calls ``announce(url,
    run_dir, token)``, :meth:`stop` ends it.  With ``view=True`` it also serves the web view of the run it
    records (``taskflow run --view``, :mod:`taskflow.operate.view`).  ``token`` is the run's secret (module
    docstring); None once :meth:`start` has found nothing to guard (a replay on loopback)."""

    def __init__(self, address: str = DEFAULT_ADDRESS,
                 announce: Callable[[str, Path | None, str | None], None] | None = None, view: bool = False) -> None:
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
        self.token: str | None = new_token()
        self._server: Any = None
        self._thread: threading.Thread | None = None
        self._control_file: Path | None = None
        self._run_dir: Path | None = None
        self._refused = 0
        self._log_lock = threading.Lock()

    def start(self, channel: OperatorChannel | None, run_dir: Path | None, view: RunView | None = None,
              routes: list[Any] | None = None) -> None:
        """Serve ``channel`` (None: a replay) and, given ``view``, the web page of the run; given ``routes``,
        those instead (``taskflow view BATCH_DIR``: the campaign page, :mod:`taskflow.operate.campaign_http`)."""
        import uvicorn

        if view is None and self.view and channel is not None and run_dir is not None:
            from taskflow.operate.view import RunView

            view = RunView(channel.mission, run_dir, live=True)
        if channel is None and is_loopback(self.host):
            self.token = None  # a replay on loopback drives nothing and shows what its owner can read anyway
        self._run_dir = run_dir if channel is not None else None
        app = (control_app(channel, self.host, view, self.token, self.refused) if routes is None
               else guarded_app(routes, self.host, self.token, self.refused))
        config = uvicorn.Config(app, log_level="warning", lifespan="off", access_log=False, timeout_graceful_shutdown=1)
        self._server = uvicorn.Server(config)
        self._thread = threading.Thread(target=self._server.run, kwargs={"sockets": [self.socket]},
                                        name="taskflow-control", daemon=True)
        self._thread.start()
        if run_dir is not None and channel is not None:
            self._control_file = run_dir / CONTROL_FILE
            pid = os.getpid()
            write_private(self._control_file, json.dumps({
                "url": self.url, "mission": channel.mission.name, "token": self.token, "pid": pid,
                "process_start": process_start(pid), "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            }) + "\n")
        if self.announce is not None:
            self.announce(self.url, run_dir, self.token)

    def refused(self, method: str, path: str, client: str, status: int, why: str) -> None:
        """Log one refused request: a line on stderr and, for a run, one in ``RUN_DIR/refused.jsonl``."""
        with self._log_lock:
            self._refused += 1
            if self._refused > MAX_REFUSED_LOGGED:
                return
            last = self._refused == MAX_REFUSED_LOGGED
            print(f"taskflow: refused {method} {path} from {client}: {why} (HTTP {status})"
                  + ("; further refusals are not logged" if last else ""), file=sys.stderr)
            if self._run_dir is not None:
                entry = {"time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "method": method, "path": path,
                         "client": client, "status": status, "why": why}
                try:
                    with open(self._run_dir / REFUSED_FILE, "a") as f:
                        f.write(json.dumps(entry) + "\n")
                except OSError:
                    pass  # the stderr line stands; a full disk must not stop the endpoint

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
    """Talks to a run's endpoint with its ``token``; every failure is a :class:`ControlError` with the
    server's message.  ``run_dir`` (from :meth:`for_run`) names the run in the messages."""

    def __init__(self, url: str, timeout: float = 10.0, token: str | None = None,
                 run_dir: str | Path | None = None) -> None:
        self.url = url.rstrip("/")
        self.timeout = timeout
        self.token = token
        self.run_dir = run_dir

    @classmethod
    def for_run(cls, run_dir: str | Path) -> ControlClient:
        """The client of the run writing ``run_dir`` (its ``control.json``: address, token, process).  A run
        whose process has ended (killed, crashed) is refused here: its ``control.json`` is stale."""
        path = Path(run_dir) / CONTROL_FILE
        try:
            info = json.loads(path.read_text())
            url = info["url"]
            token, pid, start = info.get("token"), info.get("pid"), info.get("process_start")
        except FileNotFoundError:
            what = "no such folder" if not Path(run_dir).is_dir() else (
                f"it has no {CONTROL_FILE}: the run has ended, or was started with --no-control")
            raise ControlError(f"{run_dir}: {what}") from None
        except PermissionError:
            raise ControlError(f"{path}: permission denied — only the user who started the run may operate it") from None
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ControlError(f"{path}: unreadable ({exc})") from None
        if isinstance(pid, int) and not process_alive(pid, start if isinstance(start, str) else None):
            raise ControlError(f"run {run_dir} is not running (process {pid} ended)")
        return cls(url, token=token if isinstance(token, str) else None, run_dir=run_dir)

    def state(self) -> dict[str, Any]:
        return self._call("GET", "/state")

    def mission(self) -> dict[str, Any]:
        return self._call("GET", "/mission")

    def send(self, action: str, who: str = "operator", **args: str) -> dict[str, Any]:
        """POST one action (``to=`` of a pre-emption, ``event=`` of an injection)."""
        return self._call("POST", f"/{action}", {"who": who, **args})

    def _call(self, method: str, path: str, body: dict[str, Any] | None = None) -> dict[str, Any]:
        data = json.dumps(body).encode() if body is not None else None
        headers = {"Content-Type": "application/json"}
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        req = urllib.request.Request(self.url + path, data=data, method=method, headers=headers)
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
            if self.run_dir is not None and isinstance(reason, ConnectionRefusedError):
                raise ControlError(f"run {self.run_dir} is not running (its endpoint {self.url} refuses the "
                                   "connection)") from None
            raise ControlError(f"no run answers at {self.url} ({reason}): has it ended?") from None
