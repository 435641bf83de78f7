"""The table controller interface: one small API for every transport, backends chosen by a URL scheme.

Like python-can's ``Bus``: :func:`open_table` takes ``scheme://…`` and returns a :class:`TableController` of
the backend registered for that scheme (``mavlink://HOST:PORT`` → :mod:`drivers.mavlink`; other transports
register with :func:`register_scheme`). The behaviour every backend carries is ``docs/table-controller.md``.

Units and conventions (ARCHITECTURE §2): SI; a pose is ``(surge, sway, heave [m], roll, pitch, yaw [rad])``
as in ``analysis.table.model``; tilt β > 0 is pitch = +β (+x downhill); time stamps are integer nanoseconds of
**controller time** (the controller's own monotonic clock) unless a name says ``host``. Overturn direction +1 is
towards the low side, −1 towards the high side.

Feedback arrives on a backend's receive thread and is published here: the latest :class:`TableStatus`
(:meth:`TableController.status`), and subscriptions (:class:`Subscription`) to statuses, accelerometer
batches, overturn detections (each event id once) and fault events. A subscription holds everything published
after it was made, in order, until read: none is dropped, so read it or close it.
"""

from __future__ import annotations

import importlib
import math
import queue
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, Generic, NamedTuple, TypeVar
from urllib.parse import urlsplit

import numpy as np

from analysis.table.link import LinkSettings
from analysis.table.model import TableModel
from analysis.table.setpoints import check_setpoints
from drivers.bodies import TableBody
from drivers.heap import HeapHold

T = TypeVar("T")

STOPPED_STATES = frozenset({"stopping", "faulted", "emergency_stopped", "idle"})
"""States that end a stream or a motion command before its end."""

STATUS_TIMEOUT = 5.0
"""Longest wait [s] for the status that shows what a command did (a controller reports a state change at once
and a status at least every 50 ms of its time): only a lost link takes this long, and then
:class:`TableTimeoutError` says so instead of leaving :meth:`TableController.status` behind the command."""

DEFAULT_LEAD = LinkSettings().lead_s
"""How far ahead of its first sample a setpoint chunk is sent by default [s] (``analysis.table.link``): a host
stall shorter than this never starves the table."""

LINK_GRACE = 0.2
"""Before declaring the link lost, wait at most this long [s] for a status: a host that was stalled itself (its
receive thread too) drains the statuses that queued meanwhile within it; a lost link sends none."""

WAIT_SLICE = 0.1
"""Waits for a status are cut into slices of this length [s], the link checked between them."""

TILT_AXES = ("pitch", "roll")
"""Axes of :meth:`TableController.set_tilt`: pitch (fall line +x, the study's) or roll (fall line −y)."""


# ----- errors ---------------------------------------------------------------------------------------------


class TableError(Exception):
    """Anything the table controller refused or failed to do; the message says what and in which state."""


class TableTimeoutError(TableError):
    """No answer from the controller in time (after the retries)."""


class CommandRefusedError(TableError):
    """The controller answered a command with a refusal: ``command`` (name), ``result`` (name), ``state``."""

    def __init__(self, command: str, result: str, state: str | None, why: str) -> None:
        self.command = command
        self.result = result
        self.state = state
        where = f" (table {state})" if state else ""
        super().__init__(f"{command} refused: {why}{where}")


class CommandDeniedError(CommandRefusedError):
    """Refused for a missing or bad signature (the signing key of host and controller differ)."""


class CommandRejectedError(CommandRefusedError):
    """Refused because the controller's state does not accept the command now."""


class CommandFailedError(CommandRefusedError):
    """Refused for invalid parameters, unsupported, or a motion that was cancelled before its end."""


class TableInUseError(TableError):
    """Another host owns the table (``docs/table-controller.md``, One host at a time): :meth:`TableController.connect`
    refused, the message naming the owner and since when."""


class TableLinkLostError(TableError):
    """No status from the controller for longer than the link timeout: the link, or the controller, is gone."""


class SetpointError(TableError, ValueError):
    """A trajectory the table must not play (``analysis.table.setpoints``: a sample not finite, outside the envelope
    or a leg's stroke, a step beyond the leg speed or tilt rate): refused by the host before anything is sent. A
    ValueError too, as the bad arguments of :meth:`TableController.stream` it replaces."""


class StreamAbortedError(TableError):
    """The controller stopped playing a stream before its end; ``report`` says how far it got."""

    def __init__(self, message: str, report: StreamReport) -> None:
        self.report = report
        super().__init__(message)


# ----- feedback types -------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class TableStatus:
    """One status report of the controller.

    ``t_ns`` controller time [ns]; ``state`` one of ``idle``, ``armed``, ``homing``, ``tilting``, ``streaming``,
    ``stopping``, ``faulted``, ``emergency_stopped`` (``docs/table-controller.md``); ``buffer_depth`` setpoint
    samples buffered and not yet played; ``last_chunk_seq`` the last setpoint chunk accepted; ``underruns`` dry
    spells of the setpoint buffer since power-up; ``faults`` names of the latched fault bits (e.g. ``"STREAM_SILENT"``);
    ``refused_commands`` commands and chunks refused for their signature since power-up; ``pose`` (6,) the
    achieved (measured) pose; ``host_ns`` host monotonic time [ns] the report arrived; ``buffer_capacity`` the
    setpoint samples the controller's buffer holds (0: not reported); ``samples_late`` setpoint samples that
    arrived after they were due and were skipped, since power-up; ``virtual_watchdog_s`` 0 when the controller
    keeps real time, else it runs in virtual time (an emulator at ``--speed max``) and this is its own link
    watchdog [s, host time], the silence :meth:`TableController.check_link` allows it; ``inputs`` the interlock
    inputs set now (``"door_open"``: the enclosure door; empty where the controller reports none).
    """

    t_ns: int
    state: str
    buffer_depth: int
    last_chunk_seq: int
    underruns: int
    faults: tuple[str, ...]
    refused_commands: int
    pose: np.ndarray
    host_ns: int
    buffer_capacity: int = 0
    samples_late: int = 0
    virtual_watchdog_s: float = 0.0
    inputs: tuple[str, ...] = ()


@dataclass(frozen=True, eq=False)
class AccelBatch:
    """Consecutive samples of one plate accelerometer: row k of ``samples`` (n, 3) [m/s², plate frame, specific
    force incl. gravity] was taken at ``t_start_ns + k * spacing_ns`` [ns, controller time]; ``seq`` counts the
    sensor's batches (a gap is a lost batch)."""

    sensor_id: int
    seq: int
    t_start_ns: int
    spacing_ns: int
    samples: np.ndarray

    def times_ns(self) -> np.ndarray:
        """Time of every sample [ns, controller time], int64."""
        return self.t_start_ns + self.spacing_ns * np.arange(len(self.samples), dtype=np.int64)


@dataclass(frozen=True, eq=False)
class TiltBatch:
    """Consecutive samples of one body's rocking angle from its tilt sensor (the overturn detector's channel):
    ``angles[k]`` [rad] was taken at ``t_start_ns + k * spacing_ns`` [ns, controller time]. The angle is the
    body's rotation about the plate's y axis relative to the plate, > 0 when its top has moved towards +x (the
    low side, downhill). ``body_id`` is its place in the run's bodies (as :class:`Detection`); ``seq`` counts the
    body's batches (a gap is a lost batch)."""

    body_id: int
    seq: int
    t_start_ns: int
    spacing_ns: int
    angles: np.ndarray

    def times_ns(self) -> np.ndarray:
        """Time of every sample [ns, controller time], int64."""
        return self.t_start_ns + self.spacing_ns * np.arange(len(self.angles), dtype=np.int64)


@dataclass(frozen=True)
class Detection:
    """An overturn on the plate: ``event_id`` (unique per controller run), ``body_id`` (its place in the run's
    bodies), ``direction`` (+1 low side, −1 high side), plate ``tilt`` [rad] and ``t_ns`` [ns, controller time]."""

    event_id: int
    body_id: int
    direction: int
    tilt: float
    t_ns: int


class FaultSource(NamedTuple):
    """Which device reported a fault and how: its ``node`` (on CANopen the node id, leg k's drive = node k) and
    the device's error ``code`` (CANopen: the EMCY error code, e.g. 0x8611 following error)."""

    node: int
    code: int


@dataclass(frozen=True)
class SetpointRefusal:
    """The controller refused setpoint chunk ``seq`` that reached it at ``t_ns`` [ns, controller time] for its
    values, and stopped the table (fault ``SETPOINT_REFUSED``); ``reason`` says which sample broke which limit."""

    t_ns: int
    seq: int
    reason: str


@dataclass(frozen=True)
class FaultEvent:
    """Fault bits that became set (``raised``) in the status at ``t_ns``; ``faults`` all latched, ``state`` then;
    ``sources`` the device reports that came with them, when the transport has them (CANopen: the EMCYs received
    since the previous status; empty elsewhere)."""

    t_ns: int
    raised: tuple[str, ...]
    faults: tuple[str, ...]
    state: str
    sources: tuple[FaultSource, ...] = ()


@dataclass(frozen=True, eq=False)
class StreamReport:
    """What :meth:`TableController.stream` did.

    ``chunks`` setpoint messages sent, ``samples`` poses in them; ``underruns`` dry spells the controller
    counted during the stream; ``t_start_ns``/``t_end_ns`` controller time of the first and last sample;
    ``duration`` [s] between them; ``lead`` [s] how far ahead of its first sample each chunk was due to be sent;
    ``send_lateness_ns`` (chunks,) actual send time − its deadline [ns, host clock; ≥ 0 unless the clock
    estimate moved]; ``final`` the status that ended the stream.
    """

    chunks: int
    samples: int
    underruns: int
    t_start_ns: int
    t_end_ns: int
    lead: float
    send_lateness_ns: np.ndarray
    final: TableStatus | None

    @property
    def duration(self) -> float:
        """Controller time from the first to the last sample [s]."""
        return (self.t_end_ns - self.t_start_ns) * 1e-9


# ----- subscriptions --------------------------------------------------------------------------------------


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
        items = []
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

    _TOPICS = ("status", "accel", "tilt", "detection", "fault")

    def __init__(self) -> None:
        self._lock = threading.Condition()
        self._subscribers: dict[str, list[Subscription[Any]]] = {topic: [] for topic in self._TOPICS}
        self.latest: TableStatus | None = None
        self._events: set[int] = set()
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

    def publish_accel(self, batch: AccelBatch) -> None:
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


# ----- the interface --------------------------------------------------------------------------------------


class TableController(ABC):
    """A connection to one table controller (see the module docstring and ``docs/table-controller.md``).

    Commands block until the controller acknowledged them and raise a :class:`TableError` subclass when it
    refused (:class:`CommandDeniedError`, :class:`CommandRejectedError`, :class:`CommandFailedError`) or did not answer
    (:class:`TableTimeoutError`). Use as a context manager: ``with open_table(url) as table:`` connects and closes.
    """

    def __init__(self, url: str) -> None:
        self.url = url
        self.link_timeout = LinkSettings().link_timeout_s
        """No status for this long [s] (confirmed after :data:`LINK_GRACE`) and the link is lost
        (:meth:`check_link`); the rig TOML's ``[controller] link_timeout_s``."""
        self.feedback = Feedback()
        self.heap = HeapHold()
        """Held from ``connect`` to ``close`` and refrozen as a stream starts: the collector's full passes stay
        short while the link is open (:mod:`drivers.heap`)."""

    # --- connection

    @abstractmethod
    def connect(self) -> None:
        """Hold :attr:`heap`, open the link, start heartbeats, synchronise the clocks; returns once the controller
        reported a status (:class:`TableTimeoutError` if it does not answer)."""

    @abstractmethod
    def close(self) -> None:
        """Stop heartbeats and the receive thread, close the link and every subscription, release :attr:`heap`.
        Idempotent."""

    def __enter__(self) -> TableController:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- commands

    @abstractmethod
    def arm(self) -> None:
        """Enable the drives at the current pose (from idle, faulted or emergency_stopped); clears latched faults."""

    @abstractmethod
    def disarm(self) -> None:
        """Disable the drives (only at rest: armed or faulted)."""

    @abstractmethod
    def home(self, *, wait: bool = True, timeout: float = 120.0) -> None:
        """Move to the home pose (all zero) within the table's limits; with ``wait``, return when it is there
        (:class:`CommandFailedError` if the motion was cancelled, :class:`TableTimeoutError` after ``timeout`` s)."""

    @abstractmethod
    def set_tilt(self, angle: float, axis: str = "pitch", *, wait: bool = True, timeout: float = 120.0) -> None:
        """Ramp the static tilt β = ``angle`` [rad] about ``axis`` (:data:`TILT_AXES`), jerk-limited; with
        ``wait``, return when it holds the tilt."""

    @abstractmethod
    def stream(self, t: np.ndarray, poses: np.ndarray, *, lead: float = DEFAULT_LEAD,
               on_progress: Callable[[int, int], None] | None = None,
               on_start: Callable[[int], None] | None = None) -> StreamReport:
        """Play a trajectory: ``t`` (N,) evenly spaced sample times [s] (only the spacing matters), ``poses``
        (N, 6). Blocks until the controller reports the end of the stream consumed.

        Chunks are scheduled in controller time ``lead`` s ahead of their first sample, paced by sleeps to
        absolute deadlines. ``on_progress(samples_sent, samples_total)`` is called from this thread about 10
        times a second; ``on_start(t_start_ns)`` once, before the first sample goes out, with the controller time
        [ns] the first sample is due (the time base of the feedback: a logger puts measurements beside the command
        with it). Raises :class:`StreamAbortedError` when the controller stops before the end (STOP, emergency
        stop, watchdog, fault) and the refusals of :meth:`arm` for START_STREAM.
        """

    @abstractmethod
    def stop(self) -> None:
        """Controlled stop (accepted unsigned in every state): decelerate, move home, then armed."""

    @abstractmethod
    def emergency_stop(self) -> None:
        """Stop the actuators at once (every state); only :meth:`arm` leaves ``emergency_stopped``."""

    # --- feedback

    @property
    def accel_batches_lost(self) -> int:
        """Accelerometer batches known to be missing since connect (from their sequence numbers); 0 on a transport
        whose samples carry none."""
        return 0

    def bodies(self, timeout: float = 3.0) -> tuple[TableBody, ...] | None:
        """The bodies the controller reports on its plate (`drivers.bodies`), waiting at most ``timeout`` [s] for
        them; None when this transport or controller does not report them."""
        return None

    def link_stats(self) -> dict[str, Any]:
        """The link's counters as this transport keeps them (frames, refusals, round trips); empty where it keeps
        none."""
        return {}

    def status(self) -> TableStatus:
        """The latest status received (:class:`TableError` before the first)."""
        latest = self.feedback.latest
        if latest is None:
            raise TableError(f"no status received from {self.url} yet")
        return latest

    def check_link(self) -> None:
        """Raise :class:`TableLinkLostError` when no status has arrived for :attr:`link_timeout` s — or, from a
        table whose latest status says it runs in virtual time, for its own link watchdog
        (:attr:`TableStatus.virtual_watchdog_s`) when that is longer: such a table sends its statuses at the end of
        each batch of ticks it computes, and a busy host's scheduler may hold it between them — and none comes
        within :data:`LINK_GRACE` s more (a host that was stalled itself catches up within it). Cheap while statuses
        flow."""
        latest = self.feedback.latest
        if latest is None:
            return
        allowed = max(self.link_timeout, latest.virtual_watchdog_s)
        if time.monotonic_ns() - latest.host_ns <= allowed * 1e9:
            return
        seen = latest.host_ns
        if self.feedback.wait_for(lambda: self.feedback.latest is not None and self.feedback.latest.host_ns > seen,
                                  LINK_GRACE):
            return
        silent = (time.monotonic_ns() - seen) * 1e-9
        raise TableLinkLostError(f"{self.url}: table link lost: no status for {silent:.1f} s "
                                 f"(link timeout {allowed:g} s; last: {latest.state})")

    def wait(self, predicate: Callable[[], bool], timeout: float) -> bool:
        """Wait until ``predicate()`` (evaluated under the feedback lock at every publication) holds, at most
        ``timeout`` s; whether it held. Checks the link between slices of :data:`WAIT_SLICE` s
        (:class:`TableLinkLostError`)."""
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if self.feedback.wait_for(predicate, max(min(remaining, WAIT_SLICE), 0.0)):
                return True
            self.check_link()  # also after the last slice: a caller that waits in short slices still sees it
            if remaining <= WAIT_SLICE:
                return False

    def wait_for_status(self, predicate: Callable[[TableStatus], bool], timeout: float) -> TableStatus:
        """The first status (the latest one included) for which ``predicate`` holds; :class:`TableTimeoutError`
        after ``timeout`` s, :class:`TableLinkLostError` as soon as the link is lost (:meth:`check_link`)."""
        found: list[TableStatus] = []

        def check() -> bool:
            latest = self.feedback.latest
            if latest is not None and predicate(latest):
                found.append(latest)
                return True
            return False

        if not self.wait(check, timeout):
            latest = self.feedback.latest
            raise TableTimeoutError(f"{self.url}: no matching status within {timeout} s "
                               f"(last: {latest.state if latest else 'none'})")
        return found[0]

    def wait_for_state(self, state: str, timeout: float) -> TableStatus:
        """The first status in ``state`` (see :meth:`wait_for_status`)."""
        return self.wait_for_status(lambda s: s.state == state, timeout)

    def statuses(self) -> Subscription[TableStatus]:
        """Every status from now on."""
        return self.feedback.subscribe("status")

    def accelerations(self) -> Subscription[AccelBatch]:
        """Every accelerometer batch from now on, as received (check ``seq`` for lost batches)."""
        return self.feedback.subscribe("accel")

    def tilts(self) -> Subscription[TiltBatch]:
        """Every body-tilt batch from now on, as received (check ``seq`` for lost batches); a backend whose
        controller sends none (CANopen) never puts any."""
        return self.feedback.subscribe("tilt")

    def detections(self) -> Subscription[Detection]:
        """Every overturn detection from now on, each event id once."""
        return self.feedback.subscribe("detection")

    def faults(self) -> Subscription[FaultEvent]:
        """Every fault bit that becomes set from now on."""
        return self.feedback.subscribe("fault")


# ----- the URL registry -----------------------------------------------------------------------------------

Factory = Callable[..., TableController]

_registry: dict[str, Factory] = {}

_BUILTIN = {"mavlink": "drivers.mavlink", "canopen": "drivers.canopen", "zenoh": "drivers.zenoh"}
"""Schemes whose backend module registers itself on import (imported on first use)."""


def register_scheme(scheme: str, factory: Factory) -> None:
    """Make ``open_table("scheme://…", **options)`` call ``factory(url, **options)``."""
    _registry[scheme.lower()] = factory


def open_table(url: str, **options: Any) -> TableController:
    """A controller for ``url`` (``mavlink://127.0.0.1:14600``, …), not yet connected: call
    :meth:`~TableController.connect` or use it in a ``with`` block. ``options`` go to the backend."""
    scheme = urlsplit(url).scheme.lower()
    if not scheme:
        raise ValueError(f"table URL {url!r} has no scheme; expected e.g. mavlink://127.0.0.1:14600")
    if scheme not in _registry and scheme in _BUILTIN:
        importlib.import_module(_BUILTIN[scheme])
    if scheme not in _registry:
        known = sorted(set(_registry) | set(_BUILTIN))
        raise ValueError(f"table URL {url!r}: unknown scheme {scheme!r}; known: {', '.join(known)}")
    return _registry[scheme](url, **options)


def host_port(url: str, default_host: str = "127.0.0.1") -> tuple[str, int]:
    """``(host, port)`` of ``scheme://HOST:PORT`` (:class:`ValueError` when the port is missing or bad)."""
    parts = urlsplit(url)
    try:
        port = parts.port
    except ValueError:
        port = None
    if port is None or parts.path not in ("", "/"):
        raise ValueError(f"table URL {url!r}: expected {parts.scheme or 'scheme'}://HOST:PORT")
    return parts.hostname or default_host, port


def sleep_until(deadline_ns: int) -> int:
    """Sleep until the host-monotonic time ``deadline_ns`` [ns] (never busy-wait: that starves other threads);
    how late the wake-up was [ns] (if the deadline had passed already: how late the call was)."""
    delay = deadline_ns - time.monotonic_ns()
    if delay > 0:
        time.sleep(delay * 1e-9)
    return time.monotonic_ns() - deadline_ns


def playable_poses(url: str, table: TableModel, poses: Any, spacing_s: float,
                   held: tuple[np.ndarray, float] | None) -> np.ndarray:
    """``poses`` as a float64 (N, 6) array the controller at ``url`` will play (``analysis.table.setpoints`` on
    ``table``, sampled every ``spacing_s`` [s], blended into from ``held``: the pose the table holds and how long
    before the first sample it leaves it [s]); else :class:`SetpointError` naming the first bad sample, its time
    and the limit (:class:`ValueError` for an array of another shape)."""
    arr = np.asarray(poses, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 6 or len(arr) == 0:
        raise ValueError(f"poses must have shape (N, 6) with N >= 1, got {arr.shape}")
    problem = check_setpoints(table, arr, spacing_s, previous=held)
    if problem is not None:
        after = " (from the pose the table holds)" if problem.kind == "rate" and problem.sample == 0 else ""
        raise SetpointError(f"{url}: trajectory not sent: sample {problem.sample} (t = "
                            f"{problem.sample * spacing_s:.3f} s): {problem.detail}{after}")
    return arr


def sample_spacing(t: Any, n: int) -> float:
    """The spacing [s] of ``t`` (N,) evenly spaced times, else :class:`ValueError`."""
    times = np.asarray(t, dtype=np.float64)
    if times.shape != (n,) or n < 2:
        raise ValueError(f"t must have shape ({n},) with at least 2 samples, got {times.shape}")
    steps = np.diff(times)
    spacing = float(steps.mean())
    if not (math.isfinite(spacing) and spacing > 0 and np.allclose(steps, spacing, rtol=1e-6, atol=1e-9)):
        raise ValueError("t must be evenly spaced and increasing")
    return spacing
