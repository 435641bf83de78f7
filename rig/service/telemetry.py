"""The service's telemetry: its status (``telemetry/status``, STATUS payloads) and the runs' outcomes
(``telemetry/run``, RUN payloads), published for any process on the zenoh network.

A status is published at once when the state, the session or whether a session is active changes, otherwise at
most :data:`MAX_RATE` times a second while the progress changes, and every :data:`IDLE_PERIOD` s when nothing
does (so that a monitor that subscribed late, or a client waiting on a paused session, still hears the service).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import zenoh

from protocols.zenoh.payloads import Kind, PayloadError, encode_json
from rig.service.keys import ServiceKeys

MAX_RATE = 10.0
"""Most progress publications per second [Hz] (state changes are published at once, on top)."""

IDLE_PERIOD = 1.0
"""Longest time between two status publications [s]."""


class TelemetryPublisher:
    """Publishes ``snapshot()`` (the reply fields of ``rig.service.wire``: ``state``, ``message``, ``session``,
    ``active``, ``progress``) on ``keys.status`` with ``t_ns`` and ``seq``; call :meth:`changed` from any thread
    whenever it changes. Runs its own thread for the throttled and the periodic publications."""

    def __init__(self, session: zenoh.Session, keys: ServiceKeys, snapshot: Callable[[], dict[str, Any]]) -> None:
        self._snapshot = snapshot
        self._status = session.declare_publisher(keys.status)
        self._run = session.declare_publisher(keys.run)
        self._cond = threading.Condition()
        self._dirty = False
        self._closing = False
        self._last_key: tuple[Any, ...] | None = None
        self._last_time = 0.0
        self._seq = 0
        self._outcomes: dict[tuple[Any, str], str] = {}
        self._thread = threading.Thread(target=self._loop, name="service-telemetry", daemon=True)
        self._thread.start()

    @property
    def published(self) -> int:
        """STATUS publications so far (the last one's ``seq``)."""
        return self._seq

    def changed(self) -> None:
        """The status changed: published now if its state did, else within 1/:data:`MAX_RATE` s."""
        snapshot = self._snapshot()
        with self._cond:
            if self._closing:
                return
            if self._key(snapshot) != self._last_key:
                self._publish(snapshot)
            else:
                self._dirty = True
                self._cond.notify_all()

    def close(self) -> None:
        """Stop the thread and undeclare the publishers."""
        with self._cond:
            self._closing = True
            self._cond.notify_all()
        self._thread.join(timeout=2.0)
        for publisher in (self._status, self._run):
            publisher.undeclare()

    # ----- internals ------------------------------------------------------------------------------------

    @staticmethod
    def _key(snapshot: dict[str, Any]) -> tuple[Any, ...]:
        return snapshot["state"], snapshot["session"], snapshot["active"]

    def _loop(self) -> None:
        with self._cond:
            while not self._closing:
                period = 1.0 / MAX_RATE if self._dirty else IDLE_PERIOD
                wait = self._last_time + period - time.monotonic()
                if wait > 0:
                    self._cond.wait(wait)
                    continue
                self._cond.release()
                try:
                    snapshot = self._snapshot()
                finally:
                    self._cond.acquire()
                if not self._closing:
                    self._publish(snapshot)

    def _publish(self, snapshot: dict[str, Any]) -> None:
        """Publish a status (and the runs' outcomes new in it); the caller holds the condition."""
        self._seq += 1
        self._dirty = False
        self._last_time = time.monotonic()
        self._last_key = self._key(snapshot)
        try:
            self._status.put(encode_json(Kind.STATUS, {**snapshot, "t_ns": time.time_ns(), "seq": self._seq}))
            for index, status in snapshot["progress"]["outcomes"].items():
                if self._outcomes.get((snapshot["session"], index)) != status:
                    self._outcomes[(snapshot["session"], index)] = status
                    self._run.put(encode_json(Kind.RUN, {"run": int(index), "status": status,
                                                         "session": snapshot["session"]}))
        except (PayloadError, zenoh.ZError):  # a NaN in the progress, or the session closing: skip this one
            pass
