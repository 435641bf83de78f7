"""The console's HTTP connections bounded: slow requests time out, each client holds a bounded number of
connections, and what is refused is logged once, then counted (``GET /api/state``: ``connections``).

* **Request timeout**: a connection whose request (headers and body) has not fully arrived
  :data:`REQUEST_TIMEOUT` s after it opened — or after its previous response — is closed (Slowloris holds
  connections open by sending a header a byte at a time).
* **Per client**: at most :data:`PER_CLIENT` connections from one address; a new one beyond that closes the
  client's oldest connection that is still waiting for its request (a browser sends its request at once, so the
  connections evicted are the slow ones); when none is waiting (all serve requests or WebSockets), the new one is
  closed.
* **In all**: at most :data:`TOTAL` connections, the same way; with the process's open-file limit far above it, the
  accept loop never runs out of file descriptors (what logged 16 MB of "Too many open files").
* The first connection closed for each reason is logged, with what happens to the next ones (counted, not logged).

:func:`guarded_protocol` makes uvicorn's h11 protocol class do this (``uvicorn.Config(http=…)``).
"""

from __future__ import annotations

import asyncio
import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol

REQUEST_TIMEOUT = 10.0
"""Longest time a request may take to arrive [s]."""

PER_CLIENT = 64
"""Most connections from one address."""

TOTAL = 512
"""Most connections in all."""

REASONS = {"slow": "its request did not arrive within {timeout:g} s",
           "evicted": "more than {per_client} connections from {client}: its oldest still waiting for a request "
                      "is closed",
           "refused": "more than {per_client} connections from {client} (or {total} in all), none waiting for a "
                      "request: the new one is closed"}


class ConnectionGuard:
    """The bookkeeping of the open connections (module docstring); ``say(message)`` logs."""

    def __init__(self, say: Callable[[str], None] = lambda message: None, *, timeout: float = REQUEST_TIMEOUT,
                 per_client: int = PER_CLIENT, total: int = TOTAL) -> None:
        self.say = say
        self.timeout = timeout
        self.per_client = per_client
        self.total = total
        self.counts = {reason: 0 for reason in REASONS}
        self._open: OrderedDict[Any, str] = OrderedDict()  # protocol → client address, oldest first
        self._lock = threading.Lock()

    def stats(self) -> dict[str, int]:
        """Connections open and those closed by each reason so far."""
        with self._lock:
            self._prune()
            return {"open": len(self._open), **self.counts}

    def admit(self, protocol: Any, client: str) -> bool:
        """A new connection from ``client``: True when it may stay (an older waiting one may be closed for it)."""
        with self._lock:
            self._prune()
            mine = [p for p, c in self._open.items() if c == client]
            for crowd, limit in ((mine, self.per_client), (list(self._open), self.total)):
                if len(crowd) >= limit:
                    waiting = next((p for p in crowd if p.waiting_for_request()), None)
                    if waiting is None:
                        self._note("refused", client)
                        return False
                    self._open.pop(waiting, None)
                    self._note("evicted", client)
                    waiting.close()
            self._open[protocol] = client
        return True

    def note(self, reason: str, client: str) -> None:
        with self._lock:
            self._note(reason, client)

    def _note(self, reason: str, client: str) -> None:
        self.counts[reason] += 1
        if self.counts[reason] == 1:
            why = REASONS[reason].format(timeout=self.timeout, per_client=self.per_client, total=self.total,
                                         client=client)
            self.say(f"closing a connection from {client}: {why}; further ones are counted (GET /api/state), "
                     "not logged")

    def _prune(self) -> None:
        for protocol in [p for p in self._open if p.closed()]:
            del self._open[protocol]


def guarded_protocol(guard: ConnectionGuard) -> type[H11Protocol]:
    """uvicorn's h11 protocol with ``guard`` applied (module docstring)."""

    class GuardedH11Protocol(H11Protocol):
        def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]  # as uvicorn's
            super().connection_made(transport)
            self._timer: asyncio.TimerHandle | None = None
            self._address = self.client[0] if self.client else "unknown address"
            if not guard.admit(self, self._address):
                transport.abort()
                return
            self._arm()

        def data_received(self, data: bytes) -> None:
            super().data_received(data)
            if not self.waiting_for_request():
                self._disarm()

        def on_response_complete(self) -> None:
            super().on_response_complete()
            self._arm()

        def connection_lost(self, exc: Exception | None) -> None:
            self._disarm()
            super().connection_lost(exc)

        # ----- for the guard ----------------------------------------------------------------------------

        def waiting_for_request(self) -> bool:
            """The connection is open and its request has not fully arrived (not upgraded to a WebSocket)."""
            return (not self.transport.is_closing() and self.transport.get_protocol() is self
                    and self.conn.their_state in (h11.IDLE, h11.SEND_BODY))

        def closed(self) -> bool:
            return self.transport.is_closing()

        def close(self) -> None:
            self._disarm()
            self.transport.abort()

        def _arm(self) -> None:
            self._disarm()
            if not self.transport.is_closing():
                self._timer = self.loop.call_later(guard.timeout, self._expired)

        def _disarm(self) -> None:
            timer, self._timer = getattr(self, "_timer", None), None
            if timer is not None:
                timer.cancel()

        def _expired(self) -> None:
            self._timer = None
            if self.waiting_for_request():
                guard.note("slow", self._address)
                self.close()

    return GuardedH11Protocol
