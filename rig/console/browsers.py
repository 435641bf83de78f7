"""The operator's browser sessions: where the page keeps its right to send controls, out of reach of page scripts.

The operator gives the operator token once (``POST /api/token``, header ``X-Operator-Token``). The console then
opens a **browser session**: a random 256-bit cookie (``rig_console``, ``HttpOnly``: no script can read it,
``SameSite=Strict``: no other site's page sends it, ``Path=/``, :data:`SESSION_S` long) and a random CSRF token
returned in the reply's JSON, which the page keeps in a variable of its script (never in ``localStorage``,
``sessionStorage`` or a readable cookie; after a reload it asks ``GET /api/session`` for it, which only a same-origin
page can read). A control from the page carries both: the cookie (sent by the browser) and the CSRF token in the
``X-Console-CSRF`` header. The token itself is not kept anywhere in the browser.

Each session has a number, the address and browser that unlocked it and when; the service's log names the session
(``console browser session 3, unlocked 09:12:04Z from 127.0.0.1 (HeadlessChrome/150.0) with the operator token of
'rig key'``: the token's holder, :mod:`rig.console.access`). At most
:data:`MAX_SESSIONS` are kept (the oldest forgotten); ``POST /api/lock`` ends one.
"""

from __future__ import annotations

import hmac
import secrets
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass

from rig.console.access import Grant

COOKIE = "rig_console"
"""The session cookie's name."""

CSRF_HEADER = "x-console-csrf"
"""The header a control from the page carries its session's CSRF token in."""

SESSION_S = 12 * 3600
"""How long a browser session lasts [s] (a shift)."""

MAX_SESSIONS = 64
"""Browser sessions kept at most (the least recently opened one is forgotten)."""


@dataclass(frozen=True)
class BrowserSession:
    """One unlocked browser: its number, cookie and CSRF token, who unlocked it (``client``: address, ``browser``:
    name and version from its user agent; ``grant``: the token's holder and role, ``token`` the token given, kept
    here to check it is still valid) and when (``opened``: monotonic [s], ``opened_utc``: ``HH:MM:SSZ``)."""

    number: int
    cookie: str
    csrf: str
    client: str
    browser: str
    opened: float
    opened_utc: str
    grant: Grant
    token: str

    def source(self) -> str:
        """How the service's log names a control from this session."""
        return (f"console browser session {self.number}, unlocked {self.opened_utc} from {self.client} "
                f"({self.browser}) with the {self.grant.role} token of {self.grant.name!r}")


class BrowserSessions:
    """The unlocked browsers (module docstring); thread-safe."""

    def __init__(self, lifetime: float = SESSION_S) -> None:
        self.lifetime = lifetime
        self._sessions: OrderedDict[str, BrowserSession] = OrderedDict()
        self._count = 0
        self._lock = threading.Lock()

    def open(self, client: str, browser: str, grant: Grant, token: str) -> BrowserSession:
        """A new session for the browser at ``client`` that gave ``token``, whose grant is ``grant``."""
        with self._lock:
            self._count += 1
            session = BrowserSession(self._count, secrets.token_urlsafe(32), secrets.token_urlsafe(32), client,
                                     browser, time.monotonic(), time.strftime("%H:%M:%SZ", time.gmtime()), grant,
                                     token)
            self._sessions[session.cookie] = session
            while len(self._sessions) > MAX_SESSIONS:
                self._sessions.popitem(last=False)
        return session

    def find(self, cookie: str | None) -> BrowserSession | None:
        """The live session of ``cookie`` (None: none, or expired)."""
        if not cookie:
            return None
        with self._lock:
            session = self._sessions.get(cookie)
            if session is not None and time.monotonic() - session.opened > self.lifetime:
                del self._sessions[cookie]
                return None
        return session

    def check(self, cookie: str | None, csrf: str | None) -> BrowserSession | None:
        """The session of ``cookie`` when ``csrf`` is its CSRF token (constant-time), else None."""
        session = self.find(cookie)
        if session is None or not csrf or not hmac.compare_digest(session.csrf.encode(), csrf.encode()):
            return None
        return session

    def close(self, cookie: str | None) -> None:
        with self._lock:
            self._sessions.pop(cookie or "", None)
