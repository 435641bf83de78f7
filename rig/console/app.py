"""The console's ASGI application (Starlette): one page, its WebSocket feed, the controls and the session's report.

==========================  ====================================================================================
``GET /``                   the page (``static/index.html``; uPlot vendored under ``static/vendor/uplot``)
``WS /ws``                  ``hello`` (everything known so far), then every ``status`` and ``live`` message
``GET /api/state``          the ``hello`` message, the browsers' counters (queued, sent, dropped) and the
                            connections' (open, closed as slow, evicted, refused: ``rig.console.guard``)
``POST /api/token``         the ``X-Operator-Token`` header holds the operator token: a browser session opens
                            (``rig.console.browsers``: HttpOnly cookie, the CSRF token in the reply)
``GET /api/session``        ``{"unlocked": bool, "csrf": …}`` of this browser's session (a reloaded page)
``POST /api/lock``          ends this browser's session
``POST /api/control/{cmd}`` ``pause``, ``resume``, ``abort``, ``estop``, ``start`` (``{"queued": id}``),
                            ``answer`` (``{"prompt": id, "reply": …, "fell": …}``): the service's reply
``GET /report``             the finished session's HTML report (``rig report``), made on first request
==========================  ====================================================================================

**Controls** need a JSON body (``Content-Type: application/json``), a same-origin request — a request whose ``Host``
is not one the console serves, or whose ``Origin`` (or ``Sec-Fetch-Site``) says it comes from another site, is
refused with 403 before anything else is looked at; there are no CORS headers, so a foreign page's preflight fails —
and either the browser session's cookie with its CSRF token (``X-Console-CSRF``: the page) or the operator token
itself (``X-Operator-Token``: a script or ``curl``). Every control that reaches the service is sent signed with the
rig's key and names its source (the browser session, or the token's user); the service logs it in the running
session's events. Without a token the page is read-only. A slow browser's messages are dropped
(``rig.console.hub``).

Every response carries a strict Content-Security-Policy (:data:`PAGE_POLICY`: scripts, styles and connections
from the console itself only, no inline script, no frames) and ``nosniff``; the report is served sandboxed
(:data:`REPORT_POLICY`: no script runs in it, and it has no origin to send controls from). Every text the page
shows from the telemetry is escaped (``static/console.js``).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import re
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any, Protocol

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.datastructures import MutableHeaders
from starlette.middleware import Middleware
from starlette.requests import HTTPConnection, Request
from starlette.responses import FileResponse, HTMLResponse, JSONResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from rig.console.access import RIG_KEY_GRANT, Grant, TokensFile
from rig.console.browsers import COOKIE, CSRF_HEADER, BrowserSession, BrowserSessions
from rig.console.hub import QUEUE_FRAMES, Hub
from rig.console.state import ConsoleState
from rig.console.token import token_matches

STATIC = Path(__file__).with_name("static")
"""The page, its script and style, and the vendored uPlot."""

CONTROLS = ("pause", "resume", "abort", "estop", "start", "answer")
"""The commands the page can send."""

FINAL_STATES = ("done", "faulted")

PAGE_POLICY = ("default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data:; connect-src 'self'; "
               "base-uri 'none'; form-action 'self'; frame-ancestors 'none'")
"""The Content-Security-Policy of every response but the report: nothing inline, nothing from elsewhere."""

REPORT_POLICY = ("sandbox; default-src 'none'; style-src 'unsafe-inline'; img-src data:; base-uri 'none'; "
                 "frame-ancestors 'none'")
"""The report's policy: its inline styles and data-URI figures, no script, an opaque origin."""

SECURITY_HEADERS = {"x-content-type-options": "nosniff", "referrer-policy": "no-referrer",
                    "x-frame-options": "DENY"}
"""Sent with every response (with the Content-Security-Policy)."""

MAX_BODY = 4096
"""Longest control request body read [bytes]."""


class Controls(Protocol):
    """Sends a command to the rig: ``command`` one of :data:`CONTROLS`, ``source`` who asked, ``args`` the request
    body's (``start``: ``queued``; ``answer``: ``prompt``, ``reply``, ``fell``); the reply dict (``ok``,
    ``message``, …); raises ``rig.service.ServiceError`` when refused. Blocking (called in a thread)."""

    def command(self, command: str, source: str, args: dict[str, Any]) -> dict[str, Any]: ...

    def refused(self, command: str, source: str, reason: str) -> None:
        """Have ``command`` from ``source``, refused by the console for ``reason``, logged in the session's events
        (never acted on); raises ``rig.service.ServiceError`` when it could not be passed on."""


class Console:
    """The console's state shared by the routes: what is known of the test, the browsers, the controls."""

    def __init__(self, controls: Controls | None, token: str | None, *, allowed_hosts: set[str] | None = None,
                 capacity: int = QUEUE_FRAMES, report_dir: Path | None = None, tokens: TokensFile | None = None,
                 say: Callable[[str], None] = lambda message: None) -> None:
        self.controls = controls
        self.token = token
        self.tokens = tokens
        self.say = say
        self.allowed_hosts = allowed_hosts
        self.state = ConsoleState()
        self.hub = Hub(capacity)
        self.report_dir = report_dir
        self.browsers = BrowserSessions()
        self.connection_stats: Callable[[], dict[str, int]] = dict  # the server's (rig.console.guard)
        self._reports: dict[tuple[str, float], Path] = {}

    @property
    def has_controls(self) -> bool:
        return self.controls is not None and (bool(self.token) or self.tokens is not None)

    def grant_of(self, token: str | None) -> Grant | None:
        """What ``token`` gives: the rig key's operator token, else the tokens file's entry as it is now."""
        if token_matches(self.token, token):
            return RIG_KEY_GRANT
        return self.tokens.grant(token) if self.tokens is not None else None

    def session_of(self, conn: HTTPConnection, *, csrf: bool) -> BrowserSession | None:
        """The browser session of the request's cookie (with ``csrf``: only when its CSRF header matches) whose
        token still gives what it gave when the session opened (a revoked token ends its sessions)."""
        cookie = conn.cookies.get(COOKIE)
        session = (self.browsers.check(cookie, conn.headers.get(CSRF_HEADER)) if csrf
                   else self.browsers.find(cookie))
        if session is not None and self.grant_of(session.token) != session.grant:
            self.browsers.close(cookie)
            why = "expired" if self.expired_of(session.token) is not None else "was revoked"
            self.say(f"browser session {session.number} of {session.grant.name!r} ended: its token {why}")
            return None
        return session

    def expired_of(self, token: str | None) -> Grant | None:
        """The tokens file's entry of ``token`` when it is there but past its expiry (None otherwise)."""
        return self.tokens.expired(token) if self.tokens is not None else None

    def expiry_refusal(self, token: str | None) -> str | None:
        """The refusal of an expired ``token``, naming its holder and when it expired (None: not an expired one)."""
        grant = self.expired_of(token)
        if grant is None:
            return None
        return (f"the token of {grant.name!r} expired at {grant.expiry_text()}: ask the operator for a new one "
                f"(the tokens file's expires)")

    def watch_refused(self, conn: HTTPConnection) -> str | None:
        """Why this request may not watch (None: it may). Without a tokens file anyone who reaches the console
        watches; with one, a browser session or a token (``X-Operator-Token``) of either role is needed."""
        if self.tokens is None:
            return None
        if self.session_of(conn, csrf=False) is not None or self.grant_of(conn.headers.get("x-operator-token")):
            return None
        return (self.expiry_refusal(conn.headers.get("x-operator-token"))
                or "this console shows the test to token holders only: give a viewer's or an operator's token")

    def deliver(self, kind: str, body: dict[str, Any]) -> None:
        """A telemetry publication (in the event loop's thread): folded into the state and offered to every
        browser."""
        message = self.state.on_status(body) if kind == "status" else self.state.on_live(body)
        # a live frame may be dropped for a slow browser, unless it starts a run or carries a detection or fault
        droppable = kind == "live" and "header" not in body and not body.get("detections") and not body.get("faults")
        self.hub.publish(json.dumps(message, separators=(",", ":")), droppable)

    def deliver_from(self, loop: asyncio.AbstractEventLoop) -> Callable[[str, dict[str, Any]], None]:
        """``deliver`` for another thread (zenoh's): handed to ``loop`` without waiting."""

        def deliver(kind: str, body: dict[str, Any]) -> None:
            loop.call_soon_threadsafe(self.deliver, kind, body)

        return deliver

    # ----- checks ---------------------------------------------------------------------------------------

    def foreign(self, conn: HTTPConnection) -> str | None:
        """Why the request is not same-origin (None when it is)."""
        host = conn.headers.get("host", "")
        if self.allowed_hosts is not None and host not in self.allowed_hosts:
            return f"host {host!r} is not this console's"
        origin = conn.headers.get("origin")
        if origin is not None and origin != f"{'https' if conn.url.scheme in ('https', 'wss') else 'http'}://{host}":
            return f"cross-origin request from {origin!r}"
        site = conn.headers.get("sec-fetch-site")
        if site is not None and site not in ("same-origin", "none"):
            return f"cross-site request (Sec-Fetch-Site: {site})"
        return None


BROWSERS = ("Edg", "OPR", "HeadlessChrome", "Chrome", "Firefox", "Safari")
"""User-agent products named in a control request's source, the first found in this order (Chrome's user agent
also names Safari, Edge's also Chrome)."""


def browser_of(conn: HTTPConnection) -> str:
    """The browser's name and version from its user agent (e.g. ``HeadlessChrome/131.0.6778.85``)."""
    agent = conn.headers.get("user-agent", "")
    products = dict(re.findall(r"([A-Za-z]+)/([\w.]+)", agent[:512]))
    return next((f"{b}/{products[b]}" for b in BROWSERS if b in products), agent[:40] or "no user agent")


def client_of(conn: HTTPConnection) -> str:
    """The request's peer address (the transport's, not a header's)."""
    return conn.client.host if conn.client else "unknown address"


def source_of(conn: HTTPConnection) -> str:
    """Who is connected: the console page, the browser's address and its name (the hub's label for a browser)."""
    return f"console page, browser {client_of(conn)} ({browser_of(conn)})"


def create_app(console: Console, *, on_startup: Callable[[asyncio.AbstractEventLoop], None] | None = None,
               on_shutdown: Callable[[], None] | None = None) -> Starlette:
    """The ASGI application of ``console`` (module docstring). ``on_startup(loop)`` runs when the server starts
    (subscribe to the telemetry there), ``on_shutdown()`` when it stops."""

    async def page(request: Request) -> Response:
        return HTMLResponse((STATIC / "index.html").read_text(encoding="utf-8"))

    async def state(request: Request) -> Response:
        reason = console.watch_refused(request)
        if reason is not None:
            return refused(403, f"refused: {reason}")
        return JSONResponse({**console.state.hello(console.has_controls), "stats": console.hub.stats(),
                             "connections": console.connection_stats()})

    def refused(status: int, message: str) -> Response:
        return JSONResponse({"ok": False, "message": message}, status_code=status)

    def check_request(request: Request) -> Response | None:
        """Same origin, a JSON body, a console with controls; else the refusal."""
        reason = console.foreign(request)
        if reason is not None:
            return refused(403, f"refused: {reason}")
        if request.headers.get("content-type", "").split(";")[0].strip() != "application/json":
            return refused(415, "refused: a control request has a JSON body (Content-Type: application/json)")
        if not console.has_controls:
            return refused(403, "refused: this console is read-only (no rig key: no operator token)")
        return None

    def caller(request: Request) -> tuple[str, Grant] | None:
        """Who sends this control, as the transport vouches for it (the browser session of the cookie and CSRF
        token, or the token's holder, and the peer address), never as the request body says."""
        session = console.session_of(request, csrf=True)
        if session is not None:
            return session.source(), session.grant
        grant = console.grant_of(request.headers.get("x-operator-token"))
        if grant is not None:
            return (f"{grant.role} token from {client_of(request)} ({browser_of(request)}), held by {grant.name!r}",
                    grant)
        return None

    async def token(request: Request) -> Response:
        problem = check_request(request)
        if problem is not None:
            return problem
        given = request.headers.get("x-operator-token", "").strip()
        grant = console.grant_of(given)
        if grant is None:
            expired = console.expiry_refusal(given)
            if expired is not None:
                return refused(403, f"refused: {expired}")
            return refused(403, "refused: the operator token is missing or wrong (rig service token prints it)")
        session = console.browsers.open(client_of(request), browser_of(request), grant, given)
        message = ("operator token accepted: controls unlocked for this browser" if grant.may_command else
                   f"viewer token of {grant.name!r} accepted: this browser may watch, not command")
        reply = JSONResponse({"ok": True, "message": message, "csrf": session.csrf, "session": session.number,
                              "role": grant.role})
        reply.set_cookie(COOKIE, session.cookie, max_age=int(console.browsers.lifetime), path="/", httponly=True,
                         samesite="strict", secure=request.url.scheme == "https")
        return reply

    async def browser_session(request: Request) -> Response:
        reason = console.foreign(request)
        if reason is not None:
            return refused(403, f"refused: {reason}")
        session = console.session_of(request, csrf=False)
        if session is None or not console.has_controls:
            return JSONResponse({"unlocked": False})
        return JSONResponse({"unlocked": True, "csrf": session.csrf, "session": session.number,
                             "role": session.grant.role})

    async def lock(request: Request) -> Response:
        problem = check_request(request)
        if problem is not None:
            return problem
        if console.browsers.check(request.cookies.get(COOKIE), request.headers.get(CSRF_HEADER)) is None:
            return refused(403, "refused: this browser has no session to end")
        console.browsers.close(request.cookies.get(COOKIE))
        reply = JSONResponse({"ok": True, "message": "controls locked for this browser"})
        reply.delete_cookie(COOKIE, path="/", httponly=True, samesite="strict")
        return reply

    async def control(request: Request) -> Response:
        command = request.path_params["command"]
        if command not in CONTROLS:
            return refused(404, f"unknown control {command!r}; expected one of {', '.join(CONTROLS)}")
        problem = check_request(request)
        if problem is not None:
            return problem
        who = caller(request)
        if who is None:
            expired = console.expiry_refusal(request.headers.get("x-operator-token"))
            if expired is not None:
                return refused(403, f"refused: {expired}")
            return refused(403, "refused: unlock the controls with the operator token first (rig service token "
                                "prints it); the browser session is missing, expired or its CSRF token wrong")
        source, grant = who
        if not grant.may_command:
            console.say(f"control {command} from {source}: refused (a viewer may watch only)")
            await _pass_refusal_on(console, command, source, "a viewer may watch only")
            return refused(403, f"refused: {grant.name!r} is a viewer: a viewer may watch, not command")
        args = await _json_args(request)
        if isinstance(args, str):
            return refused(400, f"refused: {args}")
        from rig.service import ServiceError

        assert console.controls is not None
        try:
            reply = await run_in_threadpool(console.controls.command, command, source, args)
        except ServiceError as exc:
            return refused(409, str(exc))
        return JSONResponse({"ok": True, "message": reply.get("message", ""), "state": reply.get("state")})

    async def report(request: Request) -> Response:
        reason = console.watch_refused(request)
        if reason is not None:
            return refused(403, f"refused: {reason}")
        status = console.state.status
        if status is None or not status.get("session") or status.get("state") not in FINAL_STATES \
                or status.get("active"):
            return refused(404, "no finished session yet: the report is made once the session is done")
        session = Path(status["session"])
        try:
            html = await run_in_threadpool(_report_of, console, session)
        except Exception as exc:  # the report could not be made: say why on the page
            return refused(500, f"the report of {session} could not be made: {type(exc).__name__}: {exc}")
        return FileResponse(html, media_type="text/html", headers={"content-security-policy": REPORT_POLICY})

    async def feed(websocket: WebSocket) -> None:
        reason = console.foreign(websocket) or console.watch_refused(websocket)
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
    async def lifespan(app: Starlette) -> AsyncIterator[None]:
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
        Route("/api/session", browser_session),
        Route("/api/lock", lock, methods=["POST"]),
        Route("/api/control/{command}", control, methods=["POST"]),
        Route("/report", report),
        WebSocketRoute("/ws", feed),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
    ], lifespan=lifespan, middleware=[Middleware(SecurityHeaders)])


class SecurityHeaders:
    """ASGI middleware: :data:`PAGE_POLICY` (unless the response set its own) and :data:`SECURITY_HEADERS` on every
    HTTP response."""

    def __init__(self, app: Any) -> None:
        self.app = app

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def with_headers(message: Any) -> None:
            if message["type"] == "http.response.start":
                headers = MutableHeaders(scope=message)
                if "content-security-policy" not in headers:
                    headers["content-security-policy"] = PAGE_POLICY
                for name, value in SECURITY_HEADERS.items():
                    headers[name] = value
            await send(message)

        await self.app(scope, receive, with_headers)


async def _json_args(request: Request) -> dict[str, Any] | str:
    """The control request's JSON object (at most :data:`MAX_BODY` bytes), or why it is not one."""
    body = b""
    async for chunk in request.stream():
        body += chunk
        if len(body) > MAX_BODY:
            return f"the request body is longer than {MAX_BODY} bytes"
    try:
        args = json.loads(body or b"{}")
    except ValueError:
        return "the request body is not JSON"
    return args if isinstance(args, dict) else "the request body is not a JSON object"


async def _pass_refusal_on(console: Console, command: str, source: str, reason: str) -> None:
    """A control the console refused, passed on to be logged in the session's events (:meth:`Controls.refused`);
    when that fails, said on the console's log."""
    from rig.service import ServiceError

    assert console.controls is not None
    try:
        await run_in_threadpool(console.controls.refused, command, source, reason)
    except ServiceError as exc:
        console.say(f"control {command} from {source}: the refusal is not in the session's events: {exc}")


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
