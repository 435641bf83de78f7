"""A run's recorder: the table's feedback (accelerations, body tilts, measured pose, detections, faults) into the
run's log.

It subscribes when made (before the stream starts, so nothing is missed) and writes from its own thread once
:meth:`RunRecorder.start` has the controller time of the drive's first sample: every time in the run's log is
seconds from that instant (the commanded trajectory's t = 0), negative for what was measured before it.
Accelerometer ids map to the run's sensor names; detection and tilt body ids are the bodies' order on the table
(the emulator's ``--body`` order, a real detector's channel order), mapped to the sequence's body ids.

With a :class:`~rig.orchestrator.limits.LimitWatch` the feedback is checked against the limit detectors before
it is written: each trip is called back at once (``on_trip``: the orchestrator acts), then written as the run's
event (its line :meth:`Trip.text`, at the crossing's time) and put into the live tap as a fault item
(``limit CHANNEL``) that the console shows.

A write that fails (the session's disk full, a session error) ends the recording at once: the recorder keeps the
error in :attr:`RunRecorder.write_error` and stops the table (a controlled stop, home), and the orchestrator ends
the run and the session saying so; the rows the session file already committed stay.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from analysis.table.controller_limits import ControllerTrip
from analysis.table.limit_detectors import CHANNELS
from drivers.controller import (
    AccelBatch,
    ControllerText,
    Detection,
    FaultEvent,
    TableController,
    TableError,
    TableStatus,
    TiltBatch,
)
from rig.orchestrator.limits import LimitWatch, Trip, controller_limits
from rig.orchestrator.live import LiveTap
from rig.orchestrator.sinks import RunSink
from rig.orchestrator.states import Progress
from rig.session import SessionError

_STOPPING = {"controlled_stop": ("stopping", "faulted", "emergency_stopped", "idle"),
             "emergency_stop": ("emergency_stopped",)}
"""The states of a status that show a trip's action taken."""

POLL_SECONDS = 0.02
"""How often the recorder drains the subscriptions at least [s]; an accelerometer batch wakes it at once."""

FEEDBACK_WAIT = 5.0
"""How long :meth:`RunRecorder.finish` waits at most [s], after its linger, for every declared accelerometer's samples
to reach the drive's end: the controller sends the last batch once it is full (MAVLink: 19 samples after the drive's
last), and a busy host or controller can take longer than the linger over it (seen: a compensation play whose last
4 ms were missing at a load average of 6–7). What has not come by then is missing (:meth:`RunRecorder.short_of`)."""

SEVERE = ("EMERGENCY", "ALERT", "CRITICAL", "ERROR", "WARNING")
"""The severities of a controller's text that are recorded as the run's events (MAV_SEVERITY's names)."""

BASELINE_SAMPLES = 200
"""Samples per sensor that give the static plate-x reading (the tilt's gravity component) for the status line."""


class RunRecorder:
    """Feeds ``run_log`` (a :class:`~rig.orchestrator.sinks.RunSink`: :class:`rig.session.RunLog`) from
    ``table``'s feedback (module docstring).

    ``sensors`` maps accelerometer ids to the log's sensor names; ``body_ids`` maps the table's body index to
    the sequence's body id; ``progress`` gets the peak horizontal acceleration and the detection count;
    ``limits`` checks the feedback and ``on_trip(trip)`` is called for each trip (module docstring).
    """

    def __init__(self, table: TableController, run_log: RunSink, sensors: dict[int, str], body_ids: list[int],
                 progress: Progress, live: LiveTap | None = None, limits: LimitWatch | None = None,
                 on_trip: Callable[[Trip], None] | None = None) -> None:
        self.run_log = run_log
        self.limits = limits
        self.on_trip = on_trip
        self.trips: list[Trip] = []
        """The limit trips of the run, in the order they were found."""
        self.stop_latency: float | None = None
        """Table time from the crossing of the first trip that stops the table (the controller's, when it tripped)
        to the first status showing it stopped [s] (None: no such trip, or no such status yet)."""
        self._first_stop: dict[str, tuple[float, str]] = {}  # stopping action -> the first status showing it
        self._timed: set[str] = set()  # the sources whose stopping trip was timed
        self.table = table
        self.live = live
        self.write_error: Exception | None = None
        """The write that failed and ended the recording (None: none did)."""
        self.sensors = sensors
        self.body_ids = body_ids
        self.progress = progress
        self.detections: list[tuple[float, int, int]] = []
        self._faults_raised: list[str] = []
        self._accel = table.accelerations()
        self._tilts = table.tilts()
        self._statuses = table.statuses()
        self._detections = table.detections()
        self._faults = table.faults()
        self._controller_trips = table.limit_trips()
        self._controller_texts = table.controller_texts()
        self._last_status_t: float | None = None  # the run time of the latest status [s]
        self._t0_ns: int | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="run-recorder", daemon=True)
        self._baseline: dict[int, list[float]] = {}
        self._undeclared: set[int] = set()
        self._undeclared_tilts: set[int] = set()
        self._inputs: tuple[str, ...] = ()
        self._accel_end: dict[int, tuple[float, float]] = {}  # sensor id → (last sample's time, spacing) [s]

    def start(self, t0_ns: int) -> None:
        """The drive's first sample is due at controller time ``t0_ns``: start writing."""
        self._t0_ns = t0_ns
        self._thread.start()

    def finish(self, linger: float = 0.0, until: float | None = None, wait: float = FEEDBACK_WAIT) -> None:
        """Keep recording ``linger`` s more (late detections, the last batches) and, with ``until`` (the drive's last
        sample [s, run time]), until every declared accelerometer's samples reach it (:meth:`short_of`), at most
        ``wait`` s more; then drain and stop."""
        if self._thread.is_alive():
            self._stop.wait(linger)
            deadline = time.monotonic() + wait
            while (until is not None and self.short_of(until) and time.monotonic() < deadline
                   and self._thread.is_alive()):
                time.sleep(POLL_SECONDS)
            self._stop.set()
            self._thread.join()
        for sub in (self._accel, self._tilts, self._statuses, self._detections, self._faults, self._controller_trips,
                    self._controller_texts):
            sub.close()

    def short_of(self, until: float) -> dict[str, float | None]:
        """The declared accelerometers whose samples so far end more than one sample before ``until`` [s, run time]:
        sensor name → the time of its last sample [s] (None: none came)."""
        short: dict[str, float | None] = {}
        for sensor_id, name in self.sensors.items():
            end = self._accel_end.get(sensor_id)
            if end is None or end[0] < until - end[1]:
                short[name] = None if end is None else end[0]
        return short

    def _loop(self) -> None:
        try:
            while not self._stop.is_set():
                try:  # woken by an accelerometer batch at once: the limit detectors see it without a poll's delay
                    first = [self._accel.get(timeout=POLL_SECONDS)]
                except TimeoutError:
                    first = []
                except TableError:  # closed: the table's connection ended
                    first = []
                    self._stop.wait(POLL_SECONDS)
                self._drain(first)
            self._drain()
        except (OSError, SessionError) as exc:
            self.write_error = exc
            with contextlib.suppress(TableError):  # stopped already, or gone: the orchestrator's stream says so
                self.table.stop()

    def _seconds(self, t_ns: int | np.ndarray) -> Any:
        assert self._t0_ns is not None
        return (np.asarray(t_ns) - self._t0_ns) * 1e-9

    def _drain(self, first: list[AccelBatch] | None = None) -> None:
        """Write (and check) everything received, after ``first`` (batches already taken from the queue); then
        the link's age up to the host time before the statuses were taken (``link.age``)."""
        now_ns = time.monotonic_ns()
        for batch in [*(first or []), *self._accel.drain()]:
            self._write_accel(batch)
        for tilt in self._tilts.drain():
            self._write_tilt(tilt)
        for trip in self._controller_trips.drain():
            self._write_controller_trip(trip)
        statuses = self._statuses.drain()
        if statuses:
            self._write_poses(statuses)
        for detection in self._detections.drain():
            self._write_detection(detection)
        for text in self._controller_texts.drain():
            self._write_controller_text(text)
        for fault in self._faults.drain():
            self._write_fault(fault)
        if self.limits is not None:
            self._tripped(self.limits.link(
                [(s.host_ns, float(self._seconds(s.t_ns))) for s in statuses], now_ns))

    def _write_accel(self, batch: AccelBatch) -> None:
        name = self.sensors.get(batch.sensor_id)
        if name is None:
            if batch.sensor_id not in self._undeclared:
                self._undeclared.add(batch.sensor_id)
                self.run_log.add_event(float(self._seconds(batch.t_start_ns)),
                                       f"accelerometer {batch.sensor_id} is not declared in the run: not logged")
            return
        times = self._seconds(batch.times_ns())
        if self.limits is not None:
            self._tripped(self.limits.accel(name, times, batch.samples))
        self.run_log.append_accel(name, times, batch.samples)
        if len(times):  # a late copy of an earlier batch never moves the end back
            last = max(float(times[-1]), self._accel_end.get(batch.sensor_id, (-np.inf, 0.0))[0])
            self._accel_end[batch.sensor_id] = (last, batch.spacing_ns * 1e-9)
        baseline = self._baseline.setdefault(batch.sensor_id, [])
        if len(baseline) < BASELINE_SAMPLES:
            baseline.extend(batch.samples[:BASELINE_SAMPLES - len(baseline), 0].tolist())
        if baseline:
            fall_line = batch.samples[:, 0] - np.mean(baseline)
            self.progress.peak_accel = max(self.progress.peak_accel, float(np.abs(fall_line).max()))
            if self.live is not None and batch.sensor_id == next(iter(self.sensors)):  # the display's sensor
                self.live.accel(batch.sensor_id, times, fall_line)

    def _write_controller_trip(self, trip: ControllerTrip) -> None:
        """A trip of the controller's own levels (it has acted already): as the host's, marked ``controller``."""
        level = trip.level
        self._tripped([Trip(trip.instance(self.sensors), level.side, trip.value, level.threshold,
                            CHANNELS[level.channel].si, float(self._seconds(trip.t_ns)), level.action, "controller")])

    def _write_controller_text(self, text: ControllerText) -> None:
        """A text the controller sent (MAVLink STATUSTEXT) of severity WARNING or worse: an event marked
        ``controller`` at the latest status's time (the text carries none; NaN before any status)."""
        if text.severity not in SEVERE:
            return
        t = math.nan if self._last_status_t is None else self._last_status_t
        line = f"controller {text.severity}: {text.text} (controller)"
        self.run_log.add_event(t, line)
        if self.live is not None:
            self.live.put("fault", t, f"controller {text.severity}", line)

    def _write_tilt(self, batch: TiltBatch) -> None:
        if not 0 <= batch.body_id < len(self.body_ids):
            if batch.body_id not in self._undeclared_tilts:
                self._undeclared_tilts.add(batch.body_id)
                self.run_log.add_event(float(self._seconds(batch.t_start_ns)),
                                       f"tilt reported for body index {batch.body_id}, which is not on the plate "
                                       f"(bodies 0–{len(self.body_ids) - 1}): not logged")
            return
        body_id, times = self.body_ids[batch.body_id], self._seconds(batch.times_ns())
        if self.limits is not None:
            self._tripped(self.limits.tilt(body_id, times, batch.angles))
        self.run_log.append_tilt(body_id, times, batch.angles)

    def _write_poses(self, statuses: list[TableStatus]) -> None:
        t = self._seconds(np.array([s.t_ns for s in statuses], dtype=np.int64))
        poses = np.array([s.pose for s in statuses])
        legs = [k for k, s in enumerate(statuses) if s.following_error is not None]  # where statuses carry them
        errors = np.array([statuses[k].following_error for k in legs]).reshape(-1, 6)
        if self.limits is not None:
            self._tripped(self.limits.poses(t, poses))
            if legs:
                self._tripped(self.limits.following_errors(t[legs], errors))
        if legs:
            self.run_log.append_following_error(t[legs], errors)
        self.run_log.append_pose(t, poses)
        self._stopped_after_trip(t, statuses)
        for when, status in zip(t.tolist(), statuses, strict=True):
            if status.inputs != self._inputs:  # a suspender's input changed during the run: a line of its own
                self._inputs = status.inputs
                self.run_log.add_event(when, f"interlock inputs: {', '.join(status.inputs) or 'none set'}")
        if self.live is not None:
            self.live.put("pose", t.tolist(), [list(s.pose) for s in statuses])
        self._last_status_t = float(t[-1])
        self.progress.table_state = statuses[-1].state
        self.progress.buffer_depth = statuses[-1].buffer_depth

    def _tripped(self, trips: list[Trip]) -> None:
        """Act on each trip first (``on_trip``), then write it (module docstring)."""
        for trip in trips:
            self.trips.append(trip)
            if self.on_trip is not None:
                self.on_trip(trip)
        for trip in trips:
            self.run_log.add_event(trip.t, trip.text())
            if self.live is not None:
                self.live.put("fault", trip.t, f"limit {trip.channel}", trip.text())
        if trips:
            self._time_stops()

    def _stopped_after_trip(self, t: np.ndarray, statuses: list[TableStatus]) -> None:
        """Keep the first status that shows the table stopped, for each stopping action; then time the trips."""
        for action, states in _STOPPING.items():
            if action not in self._first_stop:
                shown = next((k for k, status in enumerate(statuses) if status.state in states), None)
                if shown is not None:
                    self._first_stop[action] = (float(t[shown]), statuses[shown].state)
        self._time_stops()

    def _time_stops(self) -> None:
        """The first trip that stops the table of each source (host, controller) with the first status showing
        the table stopped: the latency in table time, written as an event (the two sources' trips and the
        status may come in any order: zenoh's keys are not ordered between them); :attr:`stop_latency` is the
        controller's when it tripped."""
        for trip in self.trips:
            if trip.action not in _STOPPING or trip.source in self._timed or trip.action not in self._first_stop:
                continue
            self._timed.add(trip.source)
            when, state = self._first_stop[trip.action]
            latency = when - trip.t
            if latency < 0:  # the table was stopping before this crossing (an abort, another trip): not its stop
                continue
            if self.stop_latency is None or trip.source == "controller":
                self.stop_latency = latency
            self.run_log.add_event(when, f"limit {trip.channel}: the table was {state} {latency * 1e3:.1f} ms after "
                                         f"the crossing (table time; tripped by the {trip.source})")

    def _write_detection(self, detection: Detection) -> None:
        t = float(self._seconds(detection.t_ns))
        if not 0 <= detection.body_id < len(self.body_ids):
            self.run_log.add_event(t, f"overturn reported for body index {detection.body_id}, which is not on the "
                                      f"plate (bodies 0–{len(self.body_ids) - 1}): not logged")
            return
        body_id = self.body_ids[detection.body_id]
        self.run_log.add_detection(t, body_id, detection.direction, "sensor")
        self.detections.append((t, body_id, detection.direction))
        if self.live is not None:
            self.live.put("detection", t, body_id, detection.direction)
        self.progress.detections += 1

    @property
    def faults_raised(self) -> tuple[str, ...]:
        """The fault bits the table latched while this run was recorded, each once, in order."""
        return tuple(dict.fromkeys(self._faults_raised))

    def _write_fault(self, fault: FaultEvent) -> None:
        t = float(self._seconds(fault.t_ns))
        for trip in controller_limits(fault, t):  # the controller acted already: recorded beside the host's trips
            self.run_log.add_event(trip.t, trip.text())
            if self.live is not None:
                self.live.put("fault", trip.t, f"limit {trip.channel}", trip.text())
        self._faults_raised.extend(fault.raised)
        for name in fault.raised:
            self.run_log.add_fault(t, name, f"table {fault.state}; latched: {', '.join(fault.faults)}")
            if self.live is not None:
                self.live.put("fault", t, name, f"table {fault.state}")
