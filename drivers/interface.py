"""The table controller interface: one small API for every transport (``docs/table-controller.md``).

A backend subclasses :class:`TableController` (:mod:`drivers.mavlink`, :mod:`drivers.zenoh`,
:mod:`drivers.canopen`) and registers for its URL scheme (:mod:`drivers.registry`); the helpers below are what
the backends share to stream (:func:`playable_poses`, :func:`sample_spacing`, :func:`sleep_until`).
:mod:`drivers.controller` re-exports every name here.

Units and conventions (docs/architecture.md §2): SI; a pose is ``(surge, sway, heave [m], roll, pitch, yaw [rad])``
as in ``analysis.table.model``; tilt β > 0 is pitch = +β (+x downhill); time stamps are integer nanoseconds of
**controller time** (the controller's own monotonic clock) unless a name says ``host``. Overturn direction +1 is
towards the low side, −1 towards the high side.
"""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any

import numpy as np

from analysis.table.controller_limits import ControllerLevel, ControllerTrip
from analysis.table.link import LinkSettings
from analysis.table.model import TableModel
from analysis.table.setpoints import check_setpoints
from drivers.bodies import TableBody
from drivers.errors import SetpointError, TableError, TableLinkLostError, TableTimeoutError
from drivers.feedback import (
    AccelBatch,
    ControllerText,
    Detection,
    FaultEvent,
    StreamReport,
    TableStatus,
    TiltBatch,
)
from drivers.heap import HeapHold
from drivers.hub import Feedback, Subscription

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

    def limit_trips(self) -> Subscription[ControllerTrip]:
        """Every trip of the controller's own limit levels from now on (:meth:`download_limits`), each once."""
        return self.feedback.subscribe("limit_trip")

    def controller_texts(self) -> Subscription[ControllerText]:
        """Every text the controller sends from now on (MAVLink STATUSTEXT; none on the other transports)."""
        return self.feedback.subscribe("controller_text")

    def download_limits(self, levels: tuple[ControllerLevel, ...]) -> str | None:
        """Give the controller ``levels`` for the next stream (``analysis.table.controller_limits``; the ones it
        held before are cleared first): None once it took them all, else why it cannot (this transport or this
        controller does not take levels: the host's detectors then act alone). Raises :class:`TableError` as
        the commands do."""
        return "this transport does not take limit levels"


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
