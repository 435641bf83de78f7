"""The orchestrator: a test sequence played on a table, run by run, each run logged to the session file.

:meth:`Orchestrator.run` blocks in the caller's thread and walks the plan (``docs/orchestrator.md``):

- **connecting**: the table URL is opened and armed. Before that, every run's drive has been prepared and
  checked against the table model and every body checked to stand at every angle (``Sequence.check``): a bad
  sequence is refused before anything moves.
- per angle: **tilting** (SET_TILT, held for all the angle's runs), **waiting for the operator** to place the
  bodies; per run: (waiting for the operator to confirm, if the sequence asks) the drive prepared again and
  checked (a run that cannot be played is logged ``refused`` with the reason and skipped), **running**: the run's
  group is opened in the session file with the commanded trajectory, the table's feedback is recorded while the
  drive streams (:class:`~rig.orchestrator.recorder.RunRecorder`), the overturns come from the table's sensors —
  or from the operator when the sensors report none and the sequence asks — and the run ends ``completed``, or
  ``degraded`` when anything went wrong while it moved (:func:`degradations`: an underrun, setpoints that came
  late, accelerometer batches lost, a fault latched — a clipped setpoint, a stroke limit, a chunk gap): its
  events say what and how often, ``rig analyze`` leaves it out of Fig. 13 unless asked, and ``--resume``
  plays it again. A table link lost mid-run (no status for the rig TOML's ``link_timeout_s``) ends the run
  ``interrupted`` and the session at once.
- then **stopping** (home, disarm) and **done**.

From any other thread: :meth:`pause` takes effect at the end of the current record (a record is never resumed
mid-way; the table holds its tilt while **paused**), :meth:`resume` continues, :meth:`abort` stops the table at
once (a controlled stop: decelerate, home) and :meth:`emergency_stop` brakes it; either marks the current run
``aborted`` and ends the session's invocation (``done`` after an abort, ``faulted`` after an emergency stop or a
table fault). The rig's and the sequence's **limit detectors** (``docs/limits.md``) watch the feedback while a
run records: a warning is a run event; an abort level records, pauses at the end of the run, or stops the table
(a controlled stop, or an emergency stop) and ends the run ``aborted`` with the reason ``limit CHANNEL: …``. A
session file left by any of these, or by a crash, is continued with ``rig run --resume``: the
plan entries with a completed (or refused) run are skipped, the rest run in order.
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import math
import threading
import time
from collections.abc import Callable
from typing import Any, NoReturn

import numpy as np

from analysis.table.controller_limits import controller_levels
from analysis.table.limit_detectors import CHANNELS
from analysis.table.link import BUFFER_MARGIN_S
from drivers.controller import (
    DEFAULT_LEAD,
    StreamAbortedError,
    StreamReport,
    TableController,
    TableError,
    TableLinkLostError,
    TableStatus,
    open_table,
)
from rig.orchestrator.limits import LimitWatch, Trip
from rig.orchestrator.live import LiveTap, commanded_fall_line
from rig.orchestrator.noise import WINDOW_S as NOISE_WINDOW_S
from rig.orchestrator.noise import NoiseWatch
from rig.orchestrator.recorder import RunRecorder
from rig.orchestrator.sinks import RunSink, SessionSink
from rig.orchestrator.states import (
    Operator,
    OperatorDeclinedError,
    OrchestratorState,
    Progress,
    Unattended,
    check_transition,
)
from rig.orchestrator.suspenders import POLL_SECONDS as SUSPEND_POLL
from rig.orchestrator.suspenders import conditions, suspensions
from rig.sequence import PlannedRun, Sequence, SequenceError
from rig.session import SessionError, check_room, is_disk_full, run_needs

LEAD = DEFAULT_LEAD
"""How far ahead of its first sample each setpoint chunk is sent [s] where no rig configuration says
(``[controller] lead_s``; ``analysis.table.link``): a host stall shorter than this never starves the table."""

LINGER = 0.5
"""How long the feedback is still recorded after a drive has played [s]: the last accelerometer batches and the
repetitions of a late overturn event."""

COMMAND_TIMEOUT = 120.0
"""Longest tilt or home move waited for [s]."""

State = OrchestratorState


class SessionStoppedError(Exception):
    """The session's invocation ended before its plan did (abort, emergency stop, operator, table fault);
    ``faulted``: the table needs attention (emergency stop, fault) rather than a plain resume."""

    def __init__(self, message: str, faulted: bool = False) -> None:
        super().__init__(message)
        self.faulted = faulted


class Orchestrator:
    """Plays ``sequence`` on the table at ``table_url`` into the session ``log`` (module docstring).

    ``log`` is an open :class:`rig.session.SessionLog` (new or resumed: a
    :class:`~rig.orchestrator.sinks.SessionSink`); ``table_options`` go to
    :func:`drivers.controller.open_table` (e.g. ``key_file``; ``table``, the table model every trajectory is checked
    against before it is streamed, is the sequence's rig unless given); ``sensors`` the accelerometer ids the table
    reports (logged as ``accel/<id>``; default: 0 and every one with a calibration sheet in the sequence's rig);
    ``operator`` answers the operator's steps (default: unattended);
    ``on_update(progress)`` is called from the orchestrator's threads whenever the state or the progress changes
    (at most about ten times a second while streaming).
    """

    def __init__(self, sequence: Sequence, table_url: str, log: SessionSink, *,
                 table_options: dict[str, Any] | None = None, sensors: tuple[int, ...] | None = None,
                 operator: Operator | None = None, on_update: Callable[[Progress], None] | None = None,
                 controller_limits: bool = True) -> None:
        self.sequence = sequence
        self.controller_limits = controller_limits
        """Download the abort levels that stop the table to the controller before each run (``docs/limits.md``,
        On the controller); False: the host's detectors act alone (``benchmarks/limits.py`` compares the two)."""
        self._limits_said = False  # the fallback to the host's detectors was said (once a session)
        self.table_url = table_url
        self.log = log
        self.table_options = table_options or {}
        if sensors is None:
            sensors = tuple(sorted({0, *(int(name) for name in sequence.table.sensors.sheets)}))
        self.sensors = {sensor: str(sensor) for sensor in sensors}
        self.operator: Operator = operator or Unattended()
        self.progress = Progress(runs_total=len(sequence.plan()))
        self._on_update = on_update
        self._lock = threading.Condition()
        self._pause_requested = False
        self._stop_requested: str | None = None  # "abort" | "emergency stop"
        self._stop_reason: str | None = None  # what asked for it: the kind, or "limit CHANNEL"
        self._table: TableController | None = None
        self._run_log: Any = None
        self.live = LiveTap()
        self._pending_events: list[str] = []

    # ----- control from other threads -----------------------------------------------------------------

    @property
    def state(self) -> OrchestratorState:
        return self.progress.state

    def pause(self) -> None:
        """Pause at the end of the current record (the table holds its tilt)."""
        with self._lock:
            self._pause_requested = True
            self._lock.notify_all()
        self._note("pause requested: the session pauses at the end of the current record")

    def resume(self) -> None:
        """Continue after a pause (or cancel a pause not yet taken)."""
        with self._lock:
            self._pause_requested = False
            self._lock.notify_all()
        self._note("resume requested")

    def abort(self) -> None:
        """Stop now: a controlled stop of the table (decelerate, home), the current run marked ``aborted``."""
        self._request_stop("abort")

    def emergency_stop(self) -> None:
        """Brake the table now (only ARM leaves it), the current run marked ``aborted``."""
        self._request_stop("emergency stop")

    def log_event(self, text: str) -> None:
        """A line in the session file's events (e.g. a control request and its source), from any thread: the
        current run's (t NaN: the request has no time on the run's clock), else the next run's when it begins."""
        run_log = getattr(self.log, "active_run", None)
        if run_log is not None:
            try:
                run_log.add_event(float("nan"), text)
                return
            except SessionError:  # the run ended meanwhile: the next one takes it
                pass
        with self._lock:
            self._pending_events.append(text)

    def _write_pending_events(self, run_log: Any) -> None:
        with self._lock:
            pending, self._pending_events = self._pending_events, []
        for text in pending:
            run_log.add_event(float("nan"), text)

    def _limit_trip(self, trip: Trip) -> None:
        """A limit detector tripped (from the run recorder's thread): its action, at once (``docs/limits.md``)."""
        if trip.action == "record":
            self._note(trip.text())
        elif trip.action == "pause":
            with self._lock:
                self._pause_requested = True
                self._lock.notify_all()
            self._note(f"{trip.text()}: the session pauses at the end of the run")
        else:
            self._request_stop("emergency stop" if trip.action == "emergency_stop" else "abort",
                               reason=f"limit {trip.channel}")

    def _download_limits(self, table: TableController) -> str | None:
        """Give the controller the run's abort levels that stop the table (``analysis.table.controller_limits``);
        the run's event saying which. A controller that cannot take them (or :attr:`controller_limits` False): the
        host's detectors act alone, said once a session on the status line and as the event (None otherwise)."""
        levels = controller_levels(self.sequence.table.detectors)
        if not levels:
            return None
        why = table.download_limits(levels) if self.controller_limits else "host only, as asked"
        if why is None:
            return "limit detectors on the controller: " + ", ".join(
                f"{level.channel} {level.side.replace('_', ' ')} {level.threshold:.4g} "
                f"{CHANNELS[level.channel].si}" for level in levels)
        if self._limits_said:
            return None
        self._limits_said = True
        text = (f"limit detectors on the host only ({why}): an abort level stops the table when the host sees the "
                "crossing, up to a status batch and a command later")
        self._note(text)
        return text

    def _request_stop(self, kind: str, reason: str | None = None) -> None:
        """Stop the table now: ``kind`` ``abort`` (a controlled stop) or ``emergency stop``; ``reason`` what asked
        (default: the kind), the run's and the session's end say it."""
        with self._lock:
            if self._stop_requested == "emergency stop":
                return
            self._stop_requested = kind
            self._stop_reason = reason or kind
            self._lock.notify_all()
            table = self._table
        self._note(f"{reason or kind}: {kind} requested" if reason else f"{kind} requested")
        if table is not None:
            try:
                table.emergency_stop() if kind == "emergency stop" else table.stop()
            except TableError as exc:  # the table is already stopped, or gone: the run loop reports it
                self._note(f"{kind}: {exc}")

    # ----- the session ----------------------------------------------------------------------------------

    def run(self) -> OrchestratorState:
        """Play the plan's runs that have not completed; the final state (``done`` or ``faulted``)."""
        self.sequence.check()
        done = self.log.done_plan_indices()
        plan = [run for run in self.sequence.plan() if run.plan_index not in done]
        self.progress.runs_done = self.progress.runs_total - len(plan)
        self._set(State.CONNECTING, f"connecting to {self.table_url}")
        try:
            with open_table(self.table_url, **{"table": self.sequence.table, **self.table_options}) as table:
                table.link_timeout = self.sequence.table.link.link_timeout_s
                with self._lock:
                    self._table = table
                try:
                    self._play(table, plan)
                finally:
                    with self._lock:
                        self._table = None
                    _disarm_at_rest(table)
        except SessionStoppedError as exc:
            final = State.FAULTED if exc.faulted else State.DONE
            self._set(final, str(exc))
            return final
        except TableLinkLostError as exc:
            self._set(State.FAULTED, f"interrupted: {exc}")
            return State.FAULTED
        except (TableError, OSError, SessionError) as exc:
            if is_disk_full(exc):  # the session file's disk, not the table: say so
                self._set(State.FAULTED, str(exc) if str(exc).startswith("disk full:") else f"disk full: {exc}")
                return State.FAULTED
            if isinstance(exc, SessionError):
                raise
            self._set(State.FAULTED, f"table: {exc}")
            return State.FAULTED
        self._set(State.DONE, f"{self.progress.runs_done} of {self.progress.runs_total} runs done")
        return State.DONE

    def _play(self, table: TableController, plan: list[PlannedRun]) -> None:
        self._check_stop()
        self._check_buffer(table)
        if table.status().state != "armed":
            table.arm()
        for angle_index, group in itertools.groupby(plan, key=lambda run: run.angle_index):
            runs = list(group)
            angle_deg = self.sequence.angles_deg[angle_index]
            self._check_stop()
            self._set(State.TILTING, f"tilting the plate to {angle_deg:g}°")
            self._motion(functools.partial(table.set_tilt, math.radians(angle_deg), timeout=COMMAND_TIMEOUT))
            self._set(State.WAITING, "place the bodies")
            prompt = self.sequence.operator.place_prompt(angle_deg, self.sequence.bodies, self.sequence.name)
            self._ask(functools.partial(self.operator.place_bodies, prompt))
            for run in runs:
                self._wait_while_paused()
                self._wait_while_suspended(table)
                self._play_run(table, run)
        self._set(State.STOPPING, "all runs played: home")
        self._motion(lambda: table.home(timeout=COMMAND_TIMEOUT))

    def _check_buffer(self, table: TableController) -> None:
        """Refuse (before anything moves) a lead the controller's setpoint buffer cannot hold: the rig
        configuration's ``lead_s`` and :data:`analysis.table.link.BUFFER_MARGIN_S` more, against the capacity its
        status reports (a controller that reports none is not checked)."""
        capacity = table.status().buffer_capacity
        link, rate = self.sequence.table.link, self.sequence.table.controller_rate
        needed = math.ceil((link.lead_s + BUFFER_MARGIN_S) * rate)
        if capacity and needed > capacity:
            raise SessionStoppedError(
                f"the table's setpoint buffer holds {capacity} setpoint samples ({capacity / rate:g} s), but the rig "
                f"configuration's [controller] lead_s = {link.lead_s:g} s needs {needed}: lower lead_s or raise "
                "the controller's buffer", faulted=True)

    def _play_run(self, table: TableController, run: PlannedRun) -> None:
        self.progress.run = run
        entry = self.sequence.records[run.record_index]
        try:
            drive = self.sequence.prepare(run)
        except SequenceError as exc:
            refused = self.log.begin_run(run.plan_index, record=entry.label(), scale_factor=float("nan"),
                                         angle_deg=run.angle_deg, commanded=np.zeros((0, 7)),
                                         bodies=self._bodies(), sensors=list(self.sensors.values()),
                                         attrs={"reason": str(exc)})
            self._write_pending_events(refused)
            refused.end("refused", reason=str(exc))
            self._finish(run, "refused", f"run {run.plan_index + 1} refused: {exc}")
            return
        if self.sequence.operator.confirm_before_run:
            self._set(State.WAITING, f"confirm run {run.plan_index + 1}")
            self._ask(lambda: self.operator.confirm_run(run, (
                f"{entry.label()} at {run.angle_deg:g}°, scale factor {drive.scale_factor:.3f} "
                f"({drive.governing.axis} {drive.governing.quantity}), {drive.duration:.1f} s")))
            self._wait_while_paused()
        check_room(self.log.path, run_needs(drive.duration, len(drive.t), len(self.sensors),
                                            len(self.sequence.bodies)),
                   f"run {run.plan_index + 1} ({drive.duration:.1f} s of drive, {len(self.sensors)} accelerometers, "
                   f"{len(self.sequence.bodies)} bodies)")
        limits_said = self._download_limits(table)  # before the run begins: a table error here leaves no run open
        run_log = self.log.begin_run(
            run.plan_index, record=entry.label(), scale_factor=drive.scale_factor, angle_deg=run.angle_deg,
            commanded=np.column_stack([drive.t, drive.poses]), bodies=self._bodies(),
            sensors=list(self.sensors.values()),
            attrs={"repetition": run.repetition, "governing_axis": drive.governing.axis,
                   "governing_quantity": drive.governing.quantity, "corner_frequency": drive.corner_frequency,
                   "record_start": drive.record_start, "rate": drive.rate, "table_url": self.table_url})
        self._write_pending_events(run_log)
        if limits_said is not None:
            run_log.add_event(float("nan"), limits_said)
        self.live.begin_run(self._live_header(run, entry.label(), drive))
        recorder = RunRecorder(table, run_log, self.sensors, [b.body_id for b in self.sequence.bodies],
                               self.progress, live=self.live, limits=LimitWatch(self.sequence.table.detectors),
                               on_trip=self._limit_trip)
        self.progress.samples_sent, self.progress.samples_total = 0, len(drive.t)
        self.progress.peak_accel, self.progress.detections = 0.0, 0
        self._set(State.RUNNING, f"run {run.plan_index + 1}: {entry.label()} at {run.angle_deg:g}°")
        link = self.sequence.table.link
        before, lost_before = table.status(), table.accel_batches_lost
        try:
            report = table.stream(drive.t, drive.poses, lead=link.lead_s, on_progress=self._streamed,
                                  on_start=recorder.start)
        except TableLinkLostError as exc:
            self._end_interrupted(run, recorder, run_log, exc)
        except StreamAbortedError as exc:
            if recorder.write_error is not None:
                self._end_write_failed(table, run, recorder, run_log)
            self._end_aborted(table, run, recorder, run_log, f"the table stopped the stream: {exc}")
        except TableError as exc:
            self._end_aborted(table, run, recorder, run_log, f"table error: {exc}")
        t_end = float(drive.t[-1])
        recorder.finish(LINGER, until=t_end)
        if recorder.write_error is not None:
            self._end_write_failed(table, run, recorder, run_log)
        if not recorder.detections and self.sequence.operator.ask_detections:
            self._set(State.WAITING, "which bodies fell?")
            for body_id, direction in self._ask(lambda: self.operator.which_fell(run, self.sequence.bodies)):
                run_log.add_detection(float("nan"), body_id, direction, "operator")
        problems = degradations(before, report, table.accel_batches_lost - lost_before, recorder.faults_raised,
                                recorder.short_of(t_end), t_end)
        for problem in problems:
            run_log.add_event(float("nan"), f"degraded: {problem}")
        status = "degraded" if problems else "completed"
        run_log.end(status, underruns=report.underruns, t_start_controller_ns=report.t_start_ns,
                    lead_s=link.lead_s, link_timeout_s=link.link_timeout_s,
                    buffer_capacity=before.buffer_capacity, degraded="; ".join(problems))
        note = f": {'; '.join(problems)}" if problems else ""
        self._finish(run, status, f"run {run.plan_index + 1} {status}: {len(recorder.detections)} overturns{note}")

    def _end_interrupted(self, run: PlannedRun, recorder: RunRecorder, run_log: RunSink,
                         lost: TableLinkLostError) -> NoReturn:
        """The table link was lost mid-run: log the run ``interrupted`` and end the session at once (nothing
        answers to wait for; the controller's own watchdog stops the table)."""
        recorder.finish()
        reason = f"table link lost: {lost}"
        run_log.add_event(float("nan"), f"interrupted: {reason}")
        run_log.end("interrupted", reason=reason)
        self._finish(run, "interrupted", f"run {run.plan_index + 1} interrupted: {reason}")
        raise lost

    def _end_write_failed(self, table: TableController, run: PlannedRun, recorder: RunRecorder,
                          run_log: RunSink) -> NoReturn:
        """The session file could not be written (the recorder stopped the table): wait for the table to rest, end
        the run ``interrupted`` if the file still takes it (else `rig sessions recover` / ``--resume`` will), and
        end the session with the error (``disk full: …`` when it was that)."""
        recorder.finish()
        error = recorder.write_error
        assert error is not None
        why = f"disk full: {error}" if is_disk_full(error) else f"session file: {error}"
        with contextlib.suppress(SessionError, OSError):
            run_log.add_event(float("nan"), f"interrupted: {why}")
            run_log.end("interrupted", reason=why)
        self._finish(run, "interrupted", f"run {run.plan_index + 1} interrupted: {why}")
        self._settle_after_stop(table)
        raise SessionStoppedError(why, faulted=True)

    def _end_aborted(self, table: TableController, run: PlannedRun, recorder: RunRecorder, run_log: RunSink,
                     reason: str) -> NoReturn:
        """The stream ended early: log the run ``aborted`` and stop the session (SessionStoppedError)."""
        recorder.finish(LINGER)
        why = self._stop_reason or "fault"
        run_log.add_event(float("nan"), f"{why}: {reason}")
        run_log.end("aborted", reason=f"{why}: {reason}")
        self._finish(run, "aborted", f"run {run.plan_index + 1} aborted ({why})")
        if self._stop_requested != "emergency stop":
            self._settle_after_stop(table)
        raise SessionStoppedError(f"run {run.plan_index + 1} aborted ({why}): {reason}",
                                  faulted=self._stop_requested != "abort")

    def _settle_after_stop(self, table: TableController) -> None:
        """After an abort or a table fault: wait until the table is at rest (armed home, or faulted); a lost link
        ends the wait at once (:class:`TableLinkLostError`, raised on)."""
        self._set(State.STOPPING, "the table stops and returns home")
        try:
            table.wait_for_status(lambda s: s.state in ("armed", "faulted", "emergency_stopped", "idle"),
                                  COMMAND_TIMEOUT)
        except TableLinkLostError:
            raise
        except TableError as exc:
            self._note(f"the table did not report rest: {exc}")

    # ----- steps ----------------------------------------------------------------------------------------

    def _motion(self, move: Callable[[], None]) -> None:
        """A tilt or home move; an abort during it stops the session (the table is already stopping)."""
        try:
            move()
        except TableError as exc:
            if self._stop_requested is not None:
                raise SessionStoppedError(f"{self._stop_requested} during a move: {exc}",
                                     faulted=self._stop_requested != "abort") from None
            raise
        self._check_stop()

    def _ask(self, step: Callable[[], Any]) -> Any:
        """An operator's step, as long as it takes (the link's heartbeats go on from its own thread); then the
        table must still be where it was left: a table that stopped or faulted meanwhile ends the session, saying
        why."""
        try:
            answer = step()
        except OperatorDeclinedError as exc:
            raise SessionStoppedError(f"the operator declined: {exc}") from None
        self._check_stop()
        self._check_table("while waiting for the operator")
        return answer

    def _check_table(self, when: str) -> None:
        """Raise :class:`SessionStoppedError` (faulted) when the table left its armed hold ``when`` (a watchdog or
        a fault stopped it), :class:`TableLinkLostError` when its link is lost; logged as the next run's event."""
        table = self._table
        if table is None:
            return
        table.check_link()
        status = table.status()
        if status.state != "armed":
            why = f"the table was {status.state} {when} (faults: {', '.join(status.faults) or 'none'})"
            self.log_event(why)
            raise SessionStoppedError(why, faulted=True)

    def _wait_while_paused(self) -> None:
        with self._lock:
            if not self._pause_requested:
                return
        self._set(State.PAUSED, "paused at the end of the record: resume to continue")
        while True:
            with self._lock:
                if not (self._pause_requested and self._stop_requested is None):
                    break
                self._lock.wait(0.5)
            if self._table is not None:
                self._table.check_link()  # a table lost while paused ends the session at once
        self._check_stop()
        self._check_table("while paused")

    def _wait_while_suspended(self, table: TableController) -> None:
        """Hold the sequence while a suspender's condition holds (``rig.orchestrator.suspenders``; the
        accelerometers' noise at rest: ``rig.orchestrator.noise``); each hold, each change of what holds it and its
        end are lines in the next run's events, and the status says why it waits."""
        timeout = self.sequence.table.link.link_timeout_s
        with NoiseWatch(table, self.sequence.table.sensors) as noise:
            def now() -> list[str]:
                return suspensions(table.status(), time.monotonic_ns(), timeout) + noise.reasons()

            reasons = now()
            if noise.silent:
                self.log_event(f"noise floor not checked: accelerometer(s) {', '.join(map(str, noise.silent))} sent "
                               f"no {NOISE_WINDOW_S:g} s of samples at rest")
            if not reasons:
                return
            why = "; ".join(reasons)
            self.log_event(f"suspended: {why}")
            held = f"suspended: {why}; the sequence goes on when it clears"
            self._note(held) if self.state is State.PAUSED else self._set(State.PAUSED, held)
            while reasons:
                with self._lock:
                    if self._stop_requested is not None:
                        break
                    self._lock.wait(SUSPEND_POLL)
                table.check_link()  # a link lost while suspended ends the session at once
                latest = now()
                if latest and conditions(latest) != conditions(reasons):
                    self.log_event(f"suspended: {'; '.join(latest)}")
                    self._note(f"suspended: {'; '.join(latest)}; the sequence goes on when it clears")
                reasons = latest
        self._check_stop()
        self.log_event(f"resumed: cleared ({why})")
        self._note(f"resumed: cleared ({why})")
        self._check_table("while suspended")

    def _check_stop(self) -> None:
        if self._stop_requested is not None:
            raise SessionStoppedError(f"{self._stop_reason}: {self._stop_requested} requested"
                                      if self._stop_reason != self._stop_requested
                                      else f"{self._stop_requested} requested", faulted=self._stop_requested != "abort")

    def _streamed(self, sent: int, total: int) -> None:
        self.progress.samples_sent, self.progress.samples_total = sent, total
        self._update()

    def _live_header(self, run: PlannedRun, record: str, drive: Any) -> dict[str, Any]:
        """The live tap's header of ``run`` (``rig.orchestrator.live``)."""
        durations = self.sequence._drive_durations()
        plan = self.sequence.plan()
        after = math.fsum(durations[(p.angle_index, p.record_index)] for p in plan if p.plan_index > run.plan_index
                          and self.progress.outcomes.get(p.plan_index) not in ("completed", "refused"))
        t, a = commanded_fall_line(drive)
        return {"plan_index": run.plan_index, "record": record, "angle_deg": run.angle_deg,
                "scale_factor": drive.scale_factor, "duration_s": drive.duration, "rate": drive.rate,
                "table_seconds_after": after,
                "plan": [{"plan_index": p.plan_index, "record": self.sequence.records[p.record_index].label(),
                          "angle_deg": p.angle_deg} for p in plan],
                "bodies": [{"body_id": b.body_id, "name": b.name, "b": b.body.b, "h": b.body.h, "depth": b.depth,
                            "x": b.x, "y": b.y} for b in self.sequence.bodies],
                "commanded": {"t": t, "a": a}}

    def _bodies(self) -> list[dict[str, Any]]:
        return [{"body_id": b.body_id, "name": b.name, "b": b.body.b, "h": b.body.h, "depth": b.depth,
                 "mass": b.body.mass if b.body.mass is not None else float("nan"), "x": b.x, "y": b.y,
                 "b_cg": b.body.b_cg, "h_cg": b.body.h_cg}
                for b in self.sequence.bodies]

    # ----- progress -------------------------------------------------------------------------------------

    def _finish(self, run: PlannedRun, status: str, message: str) -> None:
        self.progress.outcomes[run.plan_index] = status
        if status in ("completed", "refused"):
            self.progress.runs_done += 1
        self._note(message)

    def _set(self, state: OrchestratorState, message: str) -> None:
        """Change the state (:data:`~rig.orchestrator.states.TRANSITIONS` must allow it: else
        :class:`~rig.orchestrator.states.IllegalTransitionError`) and report ``message``."""
        check_transition(self.progress.state, state)
        self.progress.state = state
        self._note(message)

    def _note(self, message: str) -> None:
        self.progress.message = message
        self._update()

    def _update(self) -> None:
        if self._on_update is not None:
            self._on_update(self.progress)


def degradations(before: TableStatus, report: StreamReport, accel_batches_lost: int,
                 faults: tuple[str, ...], short: dict[str, float | None], t_end: float) -> list[str]:
    """What made a run that played to its end ``degraded``, each with its count (empty: ``completed``):
    underruns and late setpoints counted by the controller over the stream (``before``: its status at the start,
    ``report.final`` at the end), accelerometer batches lost on the link, fault bits latched during the run
    (``faults``: ``SETPOINT_LIMIT``/``STROKE``: a setpoint clipped to the envelope; ``CHUNK_GAP``; any other), and
    the accelerometers whose samples stop short of the drive's end ``t_end`` [s] (``short``:
    :meth:`RunRecorder.short_of`)."""
    final = report.final or before
    problems = []
    if report.underruns:
        problems.append(f"{report.underruns} setpoint buffer underrun(s)")
    late = final.samples_late - before.samples_late
    if late > 0:
        problems.append(f"{late} setpoint sample(s) arrived late and were skipped")
    if accel_batches_lost > 0:
        problems.append(f"{accel_batches_lost} accelerometer batch(es) lost")
    if faults:
        problems.append(f"fault(s) during the motion: {', '.join(faults)}")
    problems.extend(missing_tail(short, t_end))
    return problems


def missing_tail(short: dict[str, float | None], t_end: float) -> list[str]:
    """One line per accelerometer of ``short`` (:meth:`RunRecorder.short_of`) saying where its samples end against
    the drive's end ``t_end`` [s]."""
    return [f"accelerometer {name}: no samples" if end is None else
            f"accelerometer {name}: samples end at {end:.3f} s, {t_end - end:.3f} s before the drive's end"
            for name, end in short.items()]


def _disarm_at_rest(table: TableController) -> None:
    """Leave the table disarmed when it is armed (at rest) — before the connection closes, so that its heartbeat
    watchdog does not fault it; a table faulted or emergency stopped is left as it is for the operator."""
    try:
        if table.status().state == "armed":
            table.disarm()
    except TableError:
        pass
