"""The feedback hub: what a backend's receive thread publishes, and the subscriptions that hand it on.

Feedback arrives on a backend's receive thread and is published here: the latest :class:`TableStatus`
(:meth:`TableController.status`), and subscriptions (:class:`Subscription`) to statuses, accelerometer
batches, overturn detections (each event id once) and fault events. A subscription holds everything published
after it was made, in order, until read: none is dropped, so read it or close it. :mod:`drivers.controller`
re-exports :class:`Feedback` and :class:`Subscription`.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import Any, Generic, TypeVar

import numpy as np

from analysis.table.controller_limits import ControllerTrip
from analysis.table.sensors import PLATE_AXES, SensorSheets
from drivers.errors import TableError
from drivers.feedback import (
    AccelBatch,
    ControllerText,
    Detection,
    FaultEvent,
    FaultSource,
    TableStatus,
    TiltBatch,
)

T = TypeVar("T")


_CLOSED = object()


class Subscription(Generic[T]):
    """Items published after it was made, in order, none dropped (an unbounded queue: read or close it).

    Iterating blocks for the next item and ends when the subscription (or its controller) is closed;
    :meth:`get` waits at most ``timeout`` s; :meth:`drain` takes what is there without waiting.
    """

    def __init__(self, unsubscribe: Callable[[Subscription[T]], None]) -> None:
        self._queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._unsubscribe = unsubscribe
        self._closed = False

    def put(self, item: T) -> None:
        """Publish one item to this subscriber (called by the controller's receive thread)."""
        self._queue.put(item)

    def get(self, timeout: float | None = None) -> T:
        """The next item, waiting up to ``timeout`` s (None: forever); :class:`TimeoutError` if none came,
        :class:`TableError` once the subscription is closed and empty."""
        try:
            item = self._queue.get(timeout=timeout)
        except queue.Empty:
            raise TimeoutError(f"no item within {timeout} s") from None
        if item is _CLOSED:
            self._queue.put(_CLOSED)
            raise TableError("subscription closed")
        return item

    def drain(self) -> list[T]:
        """Every item queued now, without waiting."""
        items: list[T] = []
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                return items
            if item is _CLOSED:
                self._queue.put(_CLOSED)
                return items
            items.append(item)

    def __iter__(self) -> Iterator[T]:
        while True:
            try:
                yield self.get()
            except TableError:
                return

    def close(self) -> None:
        """Stop receiving; iteration ends after the items already queued."""
        if not self._closed:
            self._closed = True
            self._unsubscribe(self)
            self._queue.put(_CLOSED)

    def __enter__(self) -> Subscription[T]:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Feedback:
    """The controller's feedback as received: the latest status, its history for waiting, and subscriptions.

    Backends call :meth:`publish_status`, :meth:`publish_accel`, :meth:`publish_tilt` and
    :meth:`publish_detection` from their receive thread. Detections are de-duplicated by ``event_id`` for the life
    of this object (one connection).
    """

    _TOPICS = ("status", "accel", "tilt", "detection", "fault", "limit_trip", "controller_text")

    def __init__(self) -> None:
        self._lock = threading.Condition()
        self._subscribers: dict[str, list[Subscription[Any]]] = {topic: [] for topic in self._TOPICS}
        self.latest: TableStatus | None = None
        self._events: set[int] = set()
        self._trips: set[ControllerTrip] = set()
        self._mountings: dict[int, np.ndarray] = {}
        self.duplicate_detections = 0
        """Retransmitted overturn events dropped (the first copy of each event id was kept)."""

    def subscribe(self, topic: str) -> Subscription[Any]:
        sub: Subscription[Any] = Subscription(lambda s: self._remove(topic, s))
        with self._lock:
            self._subscribers[topic].append(sub)
        return sub

    def _remove(self, topic: str, sub: Subscription[Any]) -> None:
        with self._lock:
            if sub in self._subscribers[topic]:
                self._subscribers[topic].remove(sub)

    def _publish(self, topic: str, item: Any) -> None:
        for sub in self._subscribers[topic]:
            sub.put(item)

    def publish_status(self, status: TableStatus, sources: tuple[FaultSource, ...] = ()) -> None:
        """Publish a status; a fault event when it latches new faults (with ``sources``: the device reports that
        raised them)."""
        with self._lock:
            before = set(self.latest.faults) if self.latest is not None else set()
            self.latest = status
            self._publish("status", status)
            raised = tuple(name for name in status.faults if name not in before)
            if raised:
                self._publish("fault", FaultEvent(status.t_ns, raised, status.faults, status.state, sources))
            self._lock.notify_all()

    def mount(self, sheets: SensorSheets) -> None:
        """From now on, turn each batch of an accelerometer whose calibration sheet in ``sheets`` mounts it off the
        plate's axes from its own axes (as it reports them) into the plate frame (``f = Aᵀ s``,
        ``SensorSheet.mounting``)."""
        self._mountings = {int(name): sheet.mounting() for name, sheet in sheets.sheets.items()
                           if sheet.axes != PLATE_AXES}

    def publish_accel(self, batch: AccelBatch) -> None:
        """Publish an accelerometer batch, in the plate frame (:meth:`mount`)."""
        mounting = self._mountings.get(batch.sensor_id)
        if mounting is not None:
            batch = replace(batch, samples=np.asarray(batch.samples, dtype=float) @ mounting)
        with self._lock:
            self._publish("accel", batch)

    def publish_tilt(self, batch: TiltBatch) -> None:
        with self._lock:
            self._publish("tilt", batch)

    def publish_detection(self, detection: Detection) -> bool:
        """Publish a detection unless its event id was seen; True if it was new."""
        with self._lock:
            if detection.event_id in self._events:
                self.duplicate_detections += 1
                return False
            self._events.add(detection.event_id)
            self._publish("detection", detection)
            return True

    def publish_limit_trip(self, trip: ControllerTrip) -> None:
        """Publish a trip of the controller's own limit levels, each once (the controller repeats it)."""
        with self._lock:
            if trip not in self._trips:
                self._trips.add(trip)
                self._publish("limit_trip", trip)

    def publish_controller_text(self, text: ControllerText) -> None:
        with self._lock:
            self._publish("controller_text", text)

    def notify(self) -> None:
        """Wake :meth:`wait_for` callers (e.g. when a command's answer arrived)."""
        with self._lock:
            self._lock.notify_all()

    def wait_for(self, predicate: Callable[[], bool], timeout: float) -> bool:
        """Wait until ``predicate()`` (evaluated under the feedback lock at every publication) holds, at most
        ``timeout`` s; whether it held."""
        with self._lock:
            return self._lock.wait_for(predicate, timeout)

    def close(self) -> None:
        with self._lock:
            subscribers = [s for subs in self._subscribers.values() for s in subs]
        for sub in subscribers:
            sub.close()
        self.notify()
