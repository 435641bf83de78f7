"""The console's ASGI application (Starlette): one page, its WebSocket feed, the controls and the session's report.

==========================  ====================================================================================
``GET /``                   the page (``static/index.html``; uPlot vendored under ``static/vendor/uplot``)
``WS /ws``                  ``hello`` (everything known so far), then every ``status`` and ``live`` message
``GET /api/state``          the ``hello`` message and the browsers' counters (queued, sent, dropped)
``POST /api/token``         ``{"ok": true}`` when the ``X-Operator-Token`` header holds the operator token
``POST /api/control/{cmd}`` ``pause``, ``resume``, ``abort``, ``estop``: the service's reply (token required)
``GET /report``             the finished session's HTML report (``rig report``), made on first request
==========================  ====================================================================================

**Controls** need the operator token (``rig.console.token``) in the ``X-Operator-Token`` header, a JSON body
(``Content-Type: application/json``) and a same-origin request: a request whose ``Host`` is not one the console
serves, or whose ``Origin`` (or ``Sec-Fetch-Site``) says it comes from another site, is refused with 403 before the
token is looked at; there are no CORS headers, so a foreign page's preflight fails. Every control request that
reaches the service is logged by it in the running session's events with its source (the browser's address and
user agent). Without a token the page is read-only. A slow browser's messages are dropped (``rig.console.hub``).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import HTTPConnection, Request
from starlette.responses import FileResponse, HTMLResponse, JSONResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from rig.console.hub import QUEUE_FRAMES, Hub
from rig.console.state import ConsoleState
from rig.console.token import token_matches

STATIC = Path(__file__).with_name("static")
"""The page, its script and style, and the vendored uPlot."""

CONTROLS = ("pause", "resume", "abort", "estop")
"""The commands the page can send."""

FINAL_STATES = ("done", "faulted")


class Controls(Protocol):
    """Sends a command to the rig: ``command`` one of :data:`CONTROLS`, ``source`` who asked; the reply dict
    (``ok``, ``message``, …); raises ``rig.service.ServiceError`` when refused. Blocking (called in a thread)."""

    def command(self, command: str, source: str) -> dict[str, Any]: ...


class Console:
    """The console's state shared by the routes: what is known of the test, the browsers, the controls."""

    def __init__(self, controls: Controls | None, token: str | None, *, allowed_hosts: set[str] | None = None,
                 capacity: int = QUEUE_FRAMES, report_dir: Path | None = None) -> None:
        self.controls = controls
        self.token = token
        self.allowed_hosts = allowed_hosts
        self.state = ConsoleState()
        self.hub = Hub(capacity)
        self.report_dir = report_dir
        self._reports: dict[tuple[str, float], Path] = {}

    @property
    def has_controls(self) -> bool:
        return self.controls is not None and bool(self.token)

    def deliver(self, kind: str, body: dict[str, Any]) -> None:
        """A telemetry publication (in the event loop's thread): folded into the state and offered to every
        browser."""
        message = self.state.on_status(body) if kind == "status" else self.state.on_live(body)
        # a live frame may be dropped for a slow browser, unless it starts a run or carries a detection or fault
        droppable = kind == "live" and "header" not in body and not body.get("detections") and not body.get("faults")
        self.hub.publish(json.dumps(message, separators=(",", ":")), droppable)

    def deliver_from(self, loop: asyncio.AbstractEventLoop) -> Callable[[str, dict[str, Any]], None]:
        """``deliver`` for another thread (zenoh's): handed to ``loop`` without waiting."""
        return lambda kind, body: loop.call_soon_threadsafe(self.deliver, kind, body)

    # ----- checks ---------------------------------------------------------------------------------------

    def foreign(self, conn: HTTPConnection) -> str | None:
        """Why the request is not same-origin (None when it is)."""
        host = conn.headers.get("host", "")
        if self.allowed_hosts is not None and host not in self.allowed_hosts:
            return f"host {host!r} is not this console's"
        origin = conn.headers.get("origin")
        if origin is not None and origin not in (f"http://{host}", f"https://{host}"):
            return f"cross-origin request from {origin!r}"
        site = conn.headers.get("sec-fetch-site")
        if site is not None and site not in ("same-origin", "none"):
            return f"cross-site request (Sec-Fetch-Site: {site})"
        return None


BROWSERS = ("Edg", "OPR", "HeadlessChrome", "Chrome", "Firefox", "Safari")
"""User-agent products named in a control request's source, the first found in this order (Chrome's user agent
also names Safari, Edge's also Chrome)."""


def source_of(conn: HTTPConnection) -> str:
    """Who sent a request: the console page, the browser's address and its name and version from the user agent
    (e.g. ``console page, browser 127.0.0.1:50412 (HeadlessChrome/131.0.6778.85)``)."""
    client = f"{conn.client.host}:{conn.client.port}" if conn.client else "unknown address"
    agent = conn.headers.get("user-agent", "")
    products = dict(re.findall(r"([A-Za-z]+)/([\w.]+)", agent))
    name = next((f"{b}/{products[b]}" for b in BROWSERS if b in products), agent[:40] or "no user agent")
    return f"console page, browser {client} ({name})"


def create_app(console: Console, *, on_startup: Callable[[asyncio.AbstractEventLoop], None] | None = None,
               on_shutdown: Callable[[], None] | None = None) -> Starlette:
    """The ASGI application of ``console`` (module docstring). ``on_startup(loop)`` runs when the server starts
    (subscribe to the telemetry there), ``on_shutdown()`` when it stops."""

    async def page(request: Request) -> Response:
        return HTMLResponse((STATIC / "index.html").read_text(encoding="utf-8"))

    async def state(request: Request) -> Response:
        return JSONResponse({**console.state.hello(console.has_controls), "stats": console.hub.stats()})

    def refused(status: int, message: str) -> Response:
        return JSONResponse({"ok": False, "message": message}, status_code=status)

    def check_control(request: Request) -> Response | None:
        reason = console.foreign(request)
        if reason is not None:
            return refused(403, f"refused: {reason}")
        if request.headers.get("content-type", "").split(";")[0].strip() != "application/json":
            return refused(415, "refused: a control request has a JSON body (Content-Type: application/json)")
        if not console.has_controls:
            return refused(403, "refused: this console is read-only (no rig key: no operator token)")
        if not token_matches(console.token, request.headers.get("x-operator-token")):
            return refused(403, "refused: the operator token is missing or wrong (rig service token prints it)")
        return None

    async def token(request: Request) -> Response:
        problem = check_control(request)
        return problem or JSONResponse({"ok": True, "message": "operator token accepted"})

    async def control(request: Request) -> Response:
        command = request.path_params["command"]
        if command not in CONTROLS:
            return refused(404, f"unknown control {command!r}; expected one of {', '.join(CONTROLS)}")
        problem = check_control(request)
        if problem is not None:
            return problem
        from rig.service import ServiceError

        assert console.controls is not None
        try:
            reply = await run_in_threadpool(console.controls.command, command, source_of(request))
        except ServiceError as exc:
            return refused(409, str(exc))
        return JSONResponse({"ok": True, "message": reply.get("message", ""), "state": reply.get("state")})

    async def report(request: Request) -> Response:
        status = console.state.status
        if status is None or not status.get("session") or status.get("state") not in FINAL_STATES \
                or status.get("active"):
            return refused(404, "no finished session yet: the report is made once the session is done")
        session = Path(status["session"])
        try:
            html = await run_in_threadpool(_report_of, console, session)
        except Exception as exc:  # the report could not be made: say why on the page
            return refused(500, f"the report of {session} could not be made: {type(exc).__name__}: {exc}")
        return FileResponse(html, media_type="text/html")

    async def feed(websocket: WebSocket) -> None:
        reason = console.foreign(websocket)
        if reason is not None:
            await websocket.close(code=1008, reason=reason[:120])
            return
        await websocket.accept()
        browser = console.hub.connect(source_of(websocket))
        try:
            await websocket.send_text(json.dumps(console.state.hello(console.has_controls), separators=(",", ":")))
            receiver = asyncio.create_task(_until_closed(websocket))
            reported = 0
            while not receiver.done():
                getter = asyncio.create_task(browser.queue.get())
                done, _ = await asyncio.wait({getter, receiver}, return_when=asyncio.FIRST_COMPLETED)
                if getter not in done:
                    getter.cancel()
                    break
                await websocket.send_text(getter.result())
                browser.sent += 1
                if browser.dropped != reported:  # tell the page what it lost
                    reported = browser.dropped
                    await websocket.send_text(json.dumps({"type": "stats", "dropped": reported}))
            receiver.cancel()
        except (WebSocketDisconnect, RuntimeError, OSError):
            pass
        finally:
            console.hub.disconnect(browser)

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette):  # type: ignore[no-untyped-def]
        if on_startup is not None:
            on_startup(asyncio.get_running_loop())
        try:
            yield
        finally:
            if on_shutdown is not None:
                on_shutdown()

    return Starlette(routes=[
        Route("/", page),
        Route("/api/state", state),
        Route("/api/token", token, methods=["POST"]),
        Route("/api/control/{command}", control, methods=["POST"]),
        Route("/report", report),
        WebSocketRoute("/ws", feed),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
    ], lifespan=lifespan)


async def _until_closed(websocket: WebSocket) -> None:
    """Read (and ignore) what the browser sends until it closes."""
    with contextlib.suppress(WebSocketDisconnect, RuntimeError):
        while True:
            await websocket.receive_text()


def _report_of(console: Console, session: Path) -> Path:
    """The session's HTML report (``rig report``), made once per session file version."""
    from rig.report import write_report

    key = (str(session), session.stat().st_mtime)
    if key not in console._reports:
        directory = console.report_dir or session.parent
        output = directory / (session.name.removesuffix(".h5") + ".console-report.html")
        console._reports[key] = Path(write_report(session, output).output)
    return console._reports[key]
