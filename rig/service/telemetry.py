"""The service's telemetry: its status (``telemetry/status``, STATUS payloads), the runs' outcomes
(``telemetry/run``, RUN payloads) and the live display data (``telemetry/live``), published for any process on the
zenoh network.

A status is published at once when the state, the session or whether a session is active changes, otherwise at
most :data:`MAX_RATE` times a second while the progress changes, and every :data:`IDLE_PERIOD` s when nothing
does (so that a monitor that subscribed late, or a client waiting on a paused session, still hears the service).

:class:`LivePublisher` publishes the running session's live tap (``rig.orchestrator.live``) on ``telemetry/live``
at :data:`LIVE_RATE` frames a second: STATUS-kind JSON payloads with ``state`` ``"live"``, ``t_ns``, ``seq``,
``session`` and what arrived since the last frame — ``accel`` (``t``, ``a``: measured fall-line acceleration
[s, m/s²], 50 Hz block means), ``pose`` (``t``, ``p``: surge, sway, heave [m], roll, pitch, yaw [rad]),
``detections`` (``t``, ``body_id``, ``direction``), ``faults`` (``t``, ``name``, ``detail``, ``plan_index``: the
run it happened in) — and ``header`` (the run's header: record, angle, scale factor, duration, plan, bodies,
commanded fall-line acceleration, and ``limits``: the table's, for the display's scales) when a run begins and
every :data:`HEADER_PERIOD` s during it, so that a console that subscribes late has it. A frame holds at most what
the bounded tap holds; a frame that cannot be published is dropped (``LivePublisher.dropped``).
"""

from __future__ import annotations

import math
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

LIVE_RATE = 20.0
"""Live frames per second while a run feeds the tap [Hz]."""

HEADER_PERIOD = 2.0
"""How often the running run's header is repeated in the live frames [s]."""


def live_key(keys: ServiceKeys) -> str:
    """The live publication's key: ``shaketable/<rig>/telemetry/live``."""
    return keys.status.rsplit("/", 1)[0] + "/live"


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


def display_limits(limits: Any) -> dict[str, float]:
    """The table's limits (``analysis.table.TableLimits``) a display scales its plots by: the translations'
    displacement limits [m] and the tilt's angle limit [deg]."""
    return {"surge_m": limits.surge.displacement, "sway_m": limits.lateral.displacement,
            "heave_m": limits.heave.displacement, "tilt_deg": math.degrees(limits.tilt.angle)}


class LivePublisher:
    """Publishes the live tap of ``tap_of()`` (the running session's ``(session path, LiveTap, limits)``, or None;
    ``limits``: :func:`display_limits` of its table, or None) on :func:`live_key` (module docstring), from its own
    thread."""

    def __init__(self, session: zenoh.Session, keys: ServiceKeys,
                 tap_of: Callable[[], tuple[str | None, Any, dict[str, float] | None] | None]) -> None:
        self._publisher = session.declare_publisher(live_key(keys))
        self._tap_of = tap_of
        self._stop = threading.Event()
        self.published = 0
        self.dropped = 0
        self._header_sent: tuple[int, Any] | None = None
        self._header_time = 0.0
        self._run_of: tuple[int, Any] = (0, None)  # (id of the tap, plan_index of the run its items belong to)
        self._thread = threading.Thread(target=self._loop, name="service-live", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop the thread and undeclare the publisher."""
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._publisher.undeclare()

    def _loop(self) -> None:
        while not self._stop.wait(1.0 / LIVE_RATE):
            current = self._tap_of()
            if current is not None:
                self._frame(*current)

    def _frame(self, session: str | None, tap: Any, limits: dict[str, float] | None = None) -> None:
        """Publish what the tap holds: one frame, or one per run when a run began since the last frame (a run's
        tail and the next run's beginning never share a frame: a display clears its plots at a new header)."""
        frame = _empty_frame(session)
        items = tap.drain()
        if self._run_of[0] != id(tap):  # a new session's tap: its items before a run's header are the header's run
            begun = any(item[0] == "run" for item in items)
            self._run_of = (id(tap), None if begun or tap.header is None else tap.header.get("plan_index"))
        for item in items:
            kind = item[0]
            if kind == "run":
                self._publish(frame)
                frame = _empty_frame(session)
                frame["header"] = {**item[1], "limits": limits}
                self._run_of = (id(tap), item[1].get("plan_index"))
                self._header_sent, self._header_time = (id(tap), id(item[1])), time.monotonic()
            elif kind == "accel":
                frame["accel"]["t"].extend(item[1])
                frame["accel"]["a"].extend(item[2])
            elif kind == "pose":
                frame["pose"]["t"].extend(item[1])
                frame["pose"]["p"].extend(item[2])
            elif kind == "detection":
                frame["detections"].append({"t": item[1], "body_id": item[2], "direction": item[3]})
            elif kind == "fault":
                frame["faults"].append({"t": item[1], "name": item[2], "detail": item[3],
                                        "plan_index": self._run_of[1]})
        header = tap.header
        now = time.monotonic()
        if "header" not in frame and header is not None and (
                self._header_sent != (id(tap), id(header)) or now - self._header_time > HEADER_PERIOD):
            frame["header"] = {**header, "limits": limits}
            self._header_sent, self._header_time = (id(tap), id(header)), now
        self._publish(frame)

    def _publish(self, frame: dict[str, Any]) -> None:
        if not (frame["accel"]["t"] or frame["pose"]["t"] or frame["detections"] or frame["faults"]
                or "header" in frame):
            return
        self.published += 1
        try:
            self._publisher.put(encode_json(Kind.STATUS, {**_finite(frame), "t_ns": time.time_ns(),
                                                          "seq": self.published}))
        except (PayloadError, zenoh.ZError):
            self.dropped += 1


def _empty_frame(session: str | None) -> dict[str, Any]:
    return {"state": "live", "session": session, "accel": {"t": [], "a": []}, "pose": {"t": [], "p": []},
            "detections": [], "faults": []}


def _finite(value: Any) -> Any:
    """``value`` with non-finite floats as None (JSON has no NaN: a detection logged by the operator has t NaN)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value
