"""The emulated table controller's logic, free of any transport: states, commands, the setpoint buffer, the
reference trajectory, watchdogs and counters (``docs/table-controller.md``).

:class:`ControllerCore` is driven by its owner, which feeds it in time order: host messages (:meth:`command`,
:meth:`chunk`, :meth:`heartbeat`) stamped with the controller time they arrived, and :meth:`tick` once per
controller tick. A tick returns the **reference pose** the actuators should follow at that time and whether the
drives are braked (idle, faulted, emergency stopped: the legs hold where they are). The achieved pose comes back
through :meth:`observe`; faults seen by the physics (stroke, limits, drive) through :meth:`raise_fault`.

Times are integer nanoseconds of controller time; poses ``(surge, sway, heave [m], roll, pitch, yaw [rad])``.

A stream plays the buffer (at most ``buffer_capacity`` samples; a chunk that does not fit is refused), interpolating
linearly between samples at the tick from the pose held at START_STREAM; late samples are skipped, a repeated chunk
ignored, a reordered one played by its times, a gap's chunk that never came counted and latched as CHUNK_GAP. An
underrun (the buffer dry before END_OF_STREAM, once a sample has arrived) stops the table (UNDERRUN, ``faulted``)
— or, with ``underrun_stops=False`` (CANopen's CSP drives), decelerates to rest, holds and takes up the samples that
come again. Moves are quintic profiles within the axis limits; stopping decelerates to rest, then moves home. The
watchdogs (``watchdog_ns``: STREAM_SILENT, HEARTBEAT_LOST) count controller time, or a ``link_clock``'s [ns] in
virtual time (:meth:`ControllerCore.watch` looks without a tick).

Each rule and its reasons: docs/table-controller.md §States, §Setpoint stream and §Clock and time stamps (virtual
time).
"""

from __future__ import annotations

import bisect
import enum
import math
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np

from analysis.table.controller_limits import CLEAR_CODE, ControllerLevel, ControllerTrip
from analysis.table.model import TableModel
from analysis.table.moves import Move, axis_limits, shortest_duration
from analysis.table.setpoint_screen import SetpointScreen
from analysis.table.setpoints import SetpointProblem, check_setpoints
from sim_table.limit_levels import LimitLevels

SEQ_MODULUS = 2**32
"""Chunk sequence numbers are uint32 and wrap."""

FIRST_SEQ_LIMIT = 2**24
"""START_STREAM's first chunk number must be an integer below this (exact in a float32 parameter)."""

_SEEN_WINDOW = 4096
"""Sequence numbers remembered per stream to recognise repeated chunks."""


class State(enum.Enum):
    """Controller states (``docs/table-controller.md``)."""

    IDLE = "idle"
    ARMED = "armed"
    HOMING = "homing"
    TILTING = "tilting"
    STREAMING = "streaming"
    STOPPING = "stopping"
    FAULTED = "faulted"
    EMERGENCY_STOPPED = "emergency_stopped"


BRAKED = (State.IDLE, State.FAULTED, State.EMERGENCY_STOPPED)
"""States with the drives disabled: the legs hold where they are. (Tuples, not sets: ``in`` on a tuple compares
members by identity, a set hashes them in Python — Enum's ``__hash__`` — twice a tick.)"""

_HEARTBEAT_GUARDED = (State.ARMED, State.HOMING, State.TILTING, State.STREAMING)


class Fault(enum.IntFlag):
    """Latched fault bits (the same bits as the MAVLink dialect's SHAKETABLE_FAULT); ARM clears them."""

    DRIVE = 1
    STROKE = 2
    STREAM_SILENT = 4
    HEARTBEAT_LOST = 8
    UNSIGNED_COMMAND = 16
    SETPOINT_LIMIT = 32
    CHUNK_GAP = 64
    UNDERRUN = 128
    SETPOINT_REFUSED = 256


_STOPPING_FAULTS = (Fault.DRIVE | Fault.STREAM_SILENT | Fault.HEARTBEAT_LOST | Fault.UNDERRUN
                    | Fault.SETPOINT_REFUSED)
"""Faults that stop the table; the others only latch."""

DEFAULT_BUFFER_CAPACITY = 4000
"""Setpoint samples the buffer holds by default (4 s at 1 kHz; ``[controller] buffer_s`` of the rig TOML)."""


class Command(enum.Enum):
    """Commands of the controller."""

    ARM = "arm"
    DISARM = "disarm"
    HOME = "home"
    SET_TILT = "set_tilt"
    START_STREAM = "start_stream"
    STOP = "stop"
    EMERGENCY_STOP = "emergency_stop"
    SET_LIMIT = "set_limit"


SIGNED_COMMANDS = frozenset({Command.ARM, Command.HOME, Command.SET_TILT, Command.START_STREAM, Command.SET_LIMIT})
"""Motion commands: refused unless signed. STOP, DISARM and EMERGENCY_STOP are accepted unsigned."""


class Result(enum.Enum):
    """Answer to a command: done, started (a final :class:`Done` follows), or refused and why."""

    ACCEPTED = "accepted"
    IN_PROGRESS = "in_progress"
    DENIED = "denied"  # missing or bad signature
    REJECTED = "rejected"  # not in this state
    FAILED = "failed"  # invalid parameters
    CANCELLED = "cancelled"  # a motion ended before its target (final answer only)


class TiltAxis(enum.IntEnum):
    """SET_TILT's axis parameter: pitch (pose column 4, fall line +x) or roll (column 3, fall line −y)."""

    PITCH = 0
    ROLL = 1


@dataclass(frozen=True)
class StateChange:
    """The state changed at ``t_ns``."""

    t_ns: int
    old: State
    new: State


@dataclass(frozen=True)
class Done:
    """A command that answered IN_PROGRESS ended at ``t_ns`` with ``result`` (ACCEPTED or CANCELLED)."""

    t_ns: int
    command: Command
    result: Result


@dataclass(frozen=True)
class Refused:
    """The setpoint chunk ``seq`` that arrived at ``t_ns`` was refused: ``reason`` says which sample broke which limit
    (``chunk 12 sample 3: heave 0.3 m outside [-0.1800, 0.1800] m``); the table stops (``SETPOINT_REFUSED``)."""

    t_ns: int
    seq: int
    reason: str


@dataclass(frozen=True, eq=False)
class Snapshot:
    """What one status carries: controller time [ns], state, setpoint samples buffered, the newest chunk accepted,
    underruns, latched faults, refused commands, the measured pose (6,), the samples the buffer can hold, the
    samples that came late (skipped) since power-up, and ``virtual_watchdog_ns``: in virtual time (a core with a
    ``link_clock``) its link watchdogs' allowance [ns, host time], 0 at real time (the host allows a virtual-time
    table this much silence instead of its link timeout: ``drivers/controller.py`` ``check_link``)."""

    t_ns: int
    state: State
    buffer_depth: int
    last_chunk_seq: int
    underruns: int
    faults: Fault
    refused_commands: int
    pose: np.ndarray
    buffer_capacity: int = DEFAULT_BUFFER_CAPACITY
    samples_late: int = 0
    virtual_watchdog_ns: int = 0
    inputs: int = 0
    """The interlock inputs set now (bit 0: the enclosure door open)."""
    following_error: np.ndarray | None = None
    """Each leg's following error (6,) [m]: its commanded length minus its measured length, legs 1…6 (None: the
    core does not know the legs; the emulator loop sets it)."""


@dataclass
class Counters:
    """What the controller counted since power-up (reported at exit; some also in every status)."""

    underruns: int = 0
    refused_commands: int = 0
    commands_accepted: int = 0
    commands_rejected: int = 0
    streams_started: int = 0
    streams_completed: int = 0
    chunks_accepted: int = 0
    chunks_duplicate: int = 0
    chunks_reordered: int = 0
    chunks_missing: int = 0
    chunks_after_end: int = 0
    chunks_not_streaming: int = 0
    chunks_overflow: int = 0
    """Chunks refused because the buffer could not hold them (the host's lead exceeds the capacity)."""
    chunks_refused: int = 0
    """Chunks refused for their values (``analysis.table.setpoints``: not finite, outside the envelope or a leg's
    stroke, beyond the leg speed or tilt rate); each stops the table."""
    last_refusal: str = ""
    """Why the last refused chunk was refused."""
    samples_late: int = 0
    stops: int = 0
    emergency_stops: int = 0
    watchdog_stops: int = 0
    chunk_margin_min_ns: int | None = None
    """Smallest (first sample time − arrival time) of an accepted chunk: how much of the lead was left."""
    chunk_margin_total_ns: int = 0
    """Sum of those margins (their mean is this / ``chunks_accepted``)."""
    faults_raised: dict[str, int] = field(default_factory=dict)
    """How often each fault bit went from clear to set."""
    limit_trips: int = 0
    """Streams the controller's own limit levels stopped (``sim_table.limit_levels``)."""

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


class ControllerCore:
    """The controller's state machine and reference generator (module docstring).

    ``table`` gives the limits; ``tick_ns`` is the tick period [ns, controller time]; ``watchdog_ns`` the silence
    that stops the table [ns, controller time, or of ``link_clock`` when given: a host-monotonic clock [ns] for
    the watchdogs in virtual time]; ``pose`` (6,) where the plate rests at power-up (default home);
    ``buffer_capacity`` the setpoint samples the buffer holds; ``underrun_stops`` (below).
    """

    # the stream's state, set by _reset_stream (at power-up, a stream's start and its end); times [ns, controller]
    _buffer: deque[tuple[int, np.ndarray]]  # (time, pose (6,)) of each setpoint sample buffered
    _anchor: tuple[int, np.ndarray] | None
    _seen: set[int]
    _seen_order: deque[int]
    _expected: int
    _gaps: dict[int, int]  # chunk number skipped → time after which it is missing
    _end_seq: int | None
    _end_ns: int | None
    _last_chunk: int | None
    _received_any: bool
    _dry: bool

    def __init__(self, table: TableModel, *, tick_ns: int = 1_000_000, watchdog_ns: int = 100_000_000,
                 pose: np.ndarray | None = None, link_clock: Callable[[], int] | None = None,
                 buffer_capacity: int = DEFAULT_BUFFER_CAPACITY, underrun_stops: bool = True) -> None:
        self.table = table
        self.tick_ns = int(tick_ns)
        self.watchdog_ns = int(watchdog_ns)
        if buffer_capacity < 1:
            raise ValueError(f"buffer_capacity must be >= 1 sample, got {buffer_capacity!r}")
        self.buffer_capacity = int(buffer_capacity)
        self.underrun_stops = underrun_stops
        """An underrun is a controlled stop (the default); False: the reference decelerates, holds and takes up the
        samples that come again — what a CANopen CSP drive does with a missing target, where the master, not this
        buffer, plays the drive (its one-sample chunks stop whenever it disables the drives)."""
        self._link_clock = link_clock
        self._velocity_limit, self._acceleration_limit, self._jerk_limit = axis_limits(table)
        self._screen = SetpointScreen(table)
        self.state = State.IDLE
        self.faults = Fault(0)
        self.inputs = 0
        """The interlock inputs set now, as every status reports them (bit 0: the enclosure door open)."""
        self.counters = Counters()
        self.last_chunk_seq = 0
        self.first_stream_ns: int | None = None
        """Controller time of the first accepted START_STREAM (fault injection times count from it)."""
        self.limit_levels = LimitLevels()
        """The abort levels downloaded for the next stream (SET_LIMIT), evaluated by the emulator loop on every
        tick's accelerometer samples (:meth:`limit_trip`)."""
        self._events: list[StateChange | Done | Refused | ControllerTrip] = []
        self._p = np.zeros(6) if pose is None else np.array(pose, dtype=float)
        self._p_before, self._dt = self._p, 0.0  # the reference a tick before and that tick [s]: its velocity
        self._achieved = self._p.copy()
        self._t: int | None = None  # the last tick
        self._last_heartbeat: int | None = None
        self._move: Move | None = None
        self._motion: Command | None = None  # HOME or SET_TILT in progress
        self._stop_reason: Fault | None = None
        self._reset_stream()

    # ----- inputs -------------------------------------------------------------------------------------

    def heartbeat(self, t_ns: int) -> None:
        """The host's heartbeat arrived at ``t_ns``."""
        self._last_heartbeat = self.link_time(t_ns)

    def link_time(self, t_ns: int) -> int:
        """The watchdogs' time of a message that arrived at controller time ``t_ns`` (module docstring)."""
        return t_ns if self._link_clock is None else self._link_clock()

    @property
    def buffered_until(self) -> int | None:
        """Controller time [ns] up to which the stream's setpoints are known: the end of the stream once its last
        chunk arrived (None: no limit), else the last buffered sample's time (the held pose's when none is); None
        when not streaming."""
        if self.state is not State.STREAMING or self._end_ns is not None:
            return None
        if self._buffer:
            return self._buffer[-1][0]
        return self._t if self._t is not None else 0

    def watch(self) -> None:
        """Run the watchdogs between ticks (with a ``link_clock``: while virtual time waits for setpoints)."""
        if self._t is not None:
            self._watchdogs(self._t)

    def observe(self, achieved: np.ndarray) -> None:
        """The latest achieved pose (6,) (where ARM takes over a braked plate)."""
        self._achieved = np.array(achieved, dtype=float)

    def refuse(self) -> Result:
        """Count a command or chunk refused for its signature (also for commands unknown to the core)."""
        self.counters.refused_commands += 1
        self._latch(Fault.UNSIGNED_COMMAND)
        return Result.DENIED

    def command(self, command: Command, params: tuple[float, ...], signed: bool, t_ns: int) -> Result:
        """Execute ``command`` with its parameters (SET_TILT: angle [rad], axis; START_STREAM: first chunk
        number) arriving at ``t_ns``; ``signed``: it carried a valid signature."""
        if command in SIGNED_COMMANDS and not signed:
            return self.refuse()
        result = getattr(self, f"_do_{command.value}")(params, t_ns)
        if result in (Result.ACCEPTED, Result.IN_PROGRESS):
            self.counters.commands_accepted += 1
        else:
            self.counters.commands_rejected += 1
        return result

    def chunk(self, seq: int, t_start_ns: int, spacing_ns: int, samples: np.ndarray, end_of_stream: bool,
              signed: bool, t_ns: int) -> bool:
        """A setpoint chunk arrived at ``t_ns``: ``samples`` (n, 6), sample k due at ``t_start_ns + k spacing_ns``.
        Whether it was taken into the buffer."""
        if not signed:
            self.refuse()
            return False
        if self.state is not State.STREAMING:
            self.counters.chunks_not_streaming += 1
            return False
        if seq in self._seen:
            self.counters.chunks_duplicate += 1
            return False
        ahead = (seq - self._expected) % SEQ_MODULUS
        if self._end_seq is not None and (seq - self._end_seq) % SEQ_MODULUS < SEQ_MODULUS // 2:
            self.counters.chunks_after_end += 1
            return False
        samples = np.asarray(samples, dtype=float)
        problem = self._check(t_start_ns, spacing_ns, samples)
        if problem is not None:
            self._refuse_chunk(seq, f"chunk {seq} {problem.message()}", t_ns)
            return False
        if len(self._buffer) + len(samples) > self.buffer_capacity:
            self.counters.chunks_overflow += 1
            return False
        if ahead == 0:
            self._expected = (seq + 1) % SEQ_MODULUS
        elif ahead < SEQ_MODULUS // 2:  # a gap: due when the playback passes the last sample buffered before it
            due = self._buffer[-1][0] if self._buffer else -1
            for skipped in range(ahead):
                self._gaps[(self._expected + skipped) % SEQ_MODULUS] = due
            self._expected = (seq + 1) % SEQ_MODULUS
        else:
            self.counters.chunks_reordered += 1
            self._gaps.pop(seq, None)
        if ahead < SEQ_MODULUS // 2:  # the newest chunk (a reordered older one arriving after it does not count)
            self.last_chunk_seq = seq
        self._remember(seq)
        self.counters.chunks_accepted += 1
        self._last_chunk = self.link_time(t_ns)
        self._received_any = True
        margin = t_start_ns - t_ns
        self.counters.chunk_margin_total_ns += margin
        if self.counters.chunk_margin_min_ns is None or margin < self.counters.chunk_margin_min_ns:
            self.counters.chunk_margin_min_ns = margin
        times = t_start_ns + spacing_ns * np.arange(len(samples), dtype=np.int64)
        if end_of_stream:
            self._end_seq = seq
            self._end_ns = int(times[-1])
        self._insert(times, samples)
        return True

    def _check(self, t_start_ns: int, spacing_ns: int, samples: np.ndarray) -> SetpointProblem | None:
        """What forbids playing ``samples`` (n, 6) due from ``t_start_ns`` every ``spacing_ns`` [ns]: the checks of
        ``analysis.table.setpoints``, the steps from the sample buffered (or played last) before them and to the one
        buffered after them included; None when nothing does. A chunk the compiled screen clears
        (``analysis.table.setpoint_screen``: the same checks, with a margin) is not checked again in numpy."""
        if samples.ndim != 2 or samples.shape[1] != 6 or len(samples) == 0 or spacing_ns <= 0:
            return SetpointProblem(0, "shape", f"{samples.shape} samples spaced {spacing_ns} ns: expected (n, 6), "
                                               "spaced > 0 ns")
        t_end_ns = t_start_ns + spacing_ns * (len(samples) - 1)
        buffer = self._buffer
        if not buffer or t_start_ns > buffer[-1][0]:  # the usual chunk, after everything buffered: as the bisects
            i = j = len(buffer)
        else:
            i = bisect.bisect_left(buffer, t_start_ns, key=lambda item: item[0])
            j = bisect.bisect_right(buffer, t_end_ns, key=lambda item: item[0])
        before = buffer[i - 1] if i > 0 else self._anchor
        after = buffer[j] if j < len(buffer) else None
        previous = None if before is None else (before[1], (t_start_ns - before[0]) * 1e-9)
        following = None if after is None else (after[1], (after[0] - t_end_ns) * 1e-9)
        if self._screen.clears(samples, spacing_ns * 1e-9, previous, following):
            return None
        return check_setpoints(self.table, samples, spacing_ns * 1e-9, previous, following)

    def refuse_chunk(self, seq: int, reason: str, t_ns: int) -> None:
        """Refuse setpoint chunk ``seq``, arrived at ``t_ns``, for ``reason`` found by the endpoint (CANopen: leg
        targets outside their stroke, or with no pose): as a chunk :meth:`chunk` refuses for its values, while
        streaming (else counted in ``chunks_not_streaming``)."""
        if self.state is not State.STREAMING:
            self.counters.chunks_not_streaming += 1
            return
        self._refuse_chunk(seq, reason, t_ns)

    def _refuse_chunk(self, seq: int, reason: str, t_ns: int) -> None:
        """Refuse chunk ``seq`` for ``reason`` (arrived at ``t_ns``): count it, tell the endpoint why (a
        :class:`Refused` event) and stop the table: the buffer is discarded and the reference decelerates from where
        it is, as in an underrun (never a jump to the refused samples)."""
        self.counters.chunks_refused += 1
        self.counters.last_refusal = reason
        self._events.append(Refused(t_ns, seq, reason))
        self.raise_fault(Fault.SETPOINT_REFUSED, t_ns)

    def raise_fault(self, fault: Fault, t_ns: int) -> None:
        """A fault seen by the physics or injected: latch it; DRIVE (and the watchdogs') also stop the table."""
        self._latch(fault)
        if fault & _STOPPING_FAULTS and self.state not in BRAKED:
            self._begin_stop(t_ns, fault)

    def limit_trip(self, trip: ControllerTrip, t_ns: int) -> bool:
        """A downloaded level tripped on a sample at ``trip.t_ns``; the table acts at tick ``t_ns`` (the first tick
        after the samples were evaluated): a controlled stop (decelerate, home, then ``armed``, as STOP) or an
        emergency stop. A :class:`ControllerTrip` event reports it. Whether it acted (False: no stream was playing
        any more)."""
        if self.state is not State.STREAMING:
            return False
        self.counters.limit_trips += 1
        self._events.append(trip)
        if trip.level.action == "emergency_stop":
            self._do_emergency_stop((), t_ns)
        else:
            self._begin_stop(t_ns, None)
        return True

    # ----- the tick -------------------------------------------------------------------------------------

    def tick(self, t_ns: int) -> tuple[np.ndarray, bool]:
        """Advance to ``t_ns``: the reference pose (6,) for the actuators and whether the drives are braked."""
        dt = (t_ns - self._t) * 1e-9 if self._t is not None else self.tick_ns * 1e-9
        self._t = t_ns
        self._watchdogs(t_ns)
        state = self.state
        if state in BRAKED:
            self._p_before, self._dt = self._p, 0.0
            return self._p, True
        if state is State.STREAMING:
            if self._gaps:
                self._missing(t_ns)
            pose = self._play(t_ns, dt)
        elif state in (State.HOMING, State.TILTING):
            assert self._move is not None
            pose = self._move.at(t_ns)
            if self._arrived(self._move, t_ns):
                self._finish_motion(t_ns, Result.ACCEPTED)
                self._set_state(State.ARMED, t_ns)
        elif state is State.STOPPING:
            pose = self._stopping(t_ns, dt)
        else:  # ARMED: hold
            pose = self._p
        self._p_before, self._dt = self._p, dt
        self._p = pose
        return pose, False

    def play_buffered(self, times: list[int], start: int, stop: int) -> list[np.ndarray]:
        """Tick through ``times[start:stop]`` [ns] while each tick is a plain stream tick: streaming, no gap
        awaited, the watchdogs quiet, the buffer's first sample due at the tick itself and another buffered after
        it. Such a tick is what :meth:`tick` does (its reference is that sample, never braked) and nothing else:
        no event, fault or state change. The references (6,) of the ticks run, from ``times[start]`` on; stops at
        the first tick that is not plain (for :meth:`tick`), so the caller runs that one through :meth:`tick`."""
        if self.state is not State.STREAMING or self._gaps:
            return []
        buffer = self._buffer
        watchdog, heartbeat, silent = self.watchdog_ns, self._last_heartbeat, self._last_chunk
        if heartbeat is None:
            return []
        if self._end_ns is not None:  # the last chunk came: STREAM_SILENT no longer watches
            silent = None
        link_clock = self._link_clock
        played: list[np.ndarray] = []
        anchor = self._anchor
        for t in times[start:stop]:
            if len(buffer) < 2 or buffer[0][0] != t:
                break
            now = t if link_clock is None else link_clock()
            if now - heartbeat > watchdog or (silent is not None and now - silent > watchdog):
                break
            anchor = buffer.popleft()
            played.append(anchor[1])
        if played:  # the state the last of these ticks leaves, as tick() leaves it
            count = len(played)
            before, p_before = (self._t, self._p) if count == 1 else (times[start + count - 2], played[-2])
            self._dt = (times[start + count - 1] - before) * 1e-9 if before is not None else self.tick_ns * 1e-9
            self._p_before, self._p = p_before, played[-1]
            self._anchor, self._t, self._dry = anchor, times[start + count - 1], False
        return played

    def take_events(self) -> list[StateChange | Done | Refused | ControllerTrip]:
        """State changes, completed commands, refused chunks and limit trips since the last call, in order."""
        events, self._events = self._events, []
        return events

    def snapshot(self, t_ns: int, pose: np.ndarray) -> Snapshot:
        """The status at ``t_ns`` with the measured ``pose`` (6,)."""
        return Snapshot(t_ns, self.state, len(self._buffer), self.last_chunk_seq, self.counters.underruns,
                        self.faults, self.counters.refused_commands, pose, self.buffer_capacity,
                        self.counters.samples_late, 0 if self._link_clock is None else self.watchdog_ns,
                        self.inputs)

    # ----- commands -------------------------------------------------------------------------------------

    def _do_arm(self, params: tuple[float, ...], t_ns: int) -> Result:
        if self.state not in (State.IDLE, State.ARMED, State.FAULTED, State.EMERGENCY_STOPPED):
            return Result.REJECTED
        if self.state in BRAKED:
            self._p = self._achieved.copy()
            self._p_before, self._dt = self._p, 0.0
        self.faults = Fault(0)
        self._last_heartbeat = self.link_time(t_ns)
        self._set_state(State.ARMED, t_ns)
        return Result.ACCEPTED

    def _do_disarm(self, params: tuple[float, ...], t_ns: int) -> Result:
        self.limit_levels.clear()
        if self.state is State.IDLE:
            return Result.ACCEPTED
        if self.state not in (State.ARMED, State.FAULTED):
            return Result.REJECTED
        self._set_state(State.IDLE, t_ns)
        return Result.ACCEPTED

    def _do_home(self, params: tuple[float, ...], t_ns: int) -> Result:
        return self._start_move(Command.HOME, np.zeros(6), t_ns)

    def _do_set_tilt(self, params: tuple[float, ...], t_ns: int) -> Result:
        angle, axis = (*params, 0.0, 0.0)[:2]
        if not (math.isfinite(angle) and abs(angle) <= self.table.limits.tilt.angle) or axis not in (0.0, 1.0):
            return Result.FAILED
        target = self._p.copy()
        target[3 if int(axis) == TiltAxis.ROLL else 4] = angle
        return self._start_move(Command.SET_TILT, target, t_ns)

    def _do_start_stream(self, params: tuple[float, ...], t_ns: int) -> Result:
        first = (*params, 0.0)[0]
        if not (math.isfinite(first) and first == int(first) and 0 <= first < FIRST_SEQ_LIMIT):
            return Result.FAILED
        if self.state is not State.ARMED:
            return Result.REJECTED
        self._reset_stream()
        self.limit_levels.restart()
        self._expected = int(first)
        self._last_chunk = self.link_time(t_ns)
        self._anchor = (t_ns, self._p.copy())
        self.counters.streams_started += 1
        if self.first_stream_ns is None:
            self.first_stream_ns = t_ns
        self._set_state(State.STREAMING, t_ns)
        return Result.ACCEPTED

    def _do_stop(self, params: tuple[float, ...], t_ns: int) -> Result:
        self.counters.stops += 1
        if self.state not in BRAKED and self.state is not State.STOPPING:
            self._begin_stop(t_ns, None)
        return Result.ACCEPTED

    def _do_emergency_stop(self, params: tuple[float, ...], t_ns: int) -> Result:
        self.counters.emergency_stops += 1
        self._finish_motion(t_ns, Result.CANCELLED)
        self._reset_stream()
        self.limit_levels.clear()
        self._move = None
        self._set_state(State.EMERGENCY_STOPPED, t_ns)
        return Result.ACCEPTED

    def _do_set_limit(self, params: tuple[float, ...], t_ns: int) -> Result:
        """Download one abort level for the next stream (``analysis.table.controller_limits``; code 0 clears
        them): not while a stream plays or stops (its levels are fixed), FAILED for parameters that pack no
        level."""
        if self.state in (State.STREAMING, State.STOPPING):
            return Result.REJECTED
        if (*params, 0.0)[0] == CLEAR_CODE:
            self.limit_levels.clear()
            return Result.ACCEPTED
        try:
            self.limit_levels.add(ControllerLevel.decode(params))
        except ValueError:
            return Result.FAILED
        return Result.ACCEPTED

    def _start_move(self, command: Command, target: np.ndarray, t_ns: int) -> Result:
        if self.state is not State.ARMED:
            return Result.REJECTED
        duration = shortest_duration(target - self._p, self._velocity_limit, self._acceleration_limit,
                                      self._jerk_limit)
        if duration == 0.0:
            return Result.ACCEPTED
        self._move = Move(t_ns, self._p.copy(), target, math.ceil(duration * 1e9))
        self._motion = command
        self._set_state(State.HOMING if command is Command.HOME else State.TILTING, t_ns)
        return Result.IN_PROGRESS

    # ----- internals ------------------------------------------------------------------------------------

    def _reset_stream(self) -> None:
        self._buffer = deque()
        self._anchor = None
        self._seen = set()
        self._seen_order = deque()
        self._expected = 0
        self._gaps = {}
        self._end_seq = None
        self._end_ns = None
        self._last_chunk = None
        self._received_any = False
        self._dry = False

    def _remember(self, seq: int) -> None:
        self._seen.add(seq)
        self._seen_order.append(seq)
        if len(self._seen_order) > _SEEN_WINDOW:
            self._seen.discard(self._seen_order.popleft())

    def _missing(self, t_ns: int) -> None:
        """Count the gaps' chunks whose time the playback has passed at ``t_ns`` as missing (module docstring)."""
        due = [seq for seq, t in self._gaps.items() if t < t_ns]
        for seq in due:
            del self._gaps[seq]
        if due:
            self.counters.chunks_missing += len(due)
            self._latch(Fault.CHUNK_GAP)

    def _insert(self, times: np.ndarray, samples: np.ndarray) -> None:
        """Put the samples due after the last tick into the time-ordered buffer (a time already there is kept)."""
        last = self._t if self._t is not None else -1
        late = int(np.count_nonzero(times <= last))
        self.counters.samples_late += late
        buffer = self._buffer
        times_due = times[late:].tolist()
        if times_due and (not buffer or times_due[0] > buffer[-1][0]):  # the usual chunk: after all buffered
            buffer.extend(zip(times_due, samples[late:], strict=True))
            return
        for t, pose in zip(times_due, samples[late:], strict=True):
            if not buffer or t > buffer[-1][0]:
                buffer.append((t, pose))
                continue
            i = bisect.bisect_left(buffer, t, key=lambda item: item[0])
            if buffer[i][0] != t:
                buffer.insert(i, (t, pose))

    def _play(self, t_ns: int, dt: float) -> np.ndarray:
        buffer = self._buffer
        while buffer and buffer[0][0] <= t_ns:
            self._anchor = buffer.popleft()
        assert self._anchor is not None
        ta, pa = self._anchor
        if buffer:
            self._dry = False
            if t_ns == ta:  # a tick on a sample (the usual grid): the sample itself
                return pa
            tb, pb = buffer[0]
            return pa + (pb - pa) * ((t_ns - ta) / (tb - ta))
        end = self._end_ns
        if end is not None and t_ns >= end:  # the end of the stream consumed: hold its last pose
            self.counters.streams_completed += 1
            self._set_state(State.ARMED, t_ns)
            self._reset_stream()
            self.limit_levels.clear()
            return pa if ta == end else self._p
        if ta == t_ns:
            return pa
        if not self._received_any:  # nothing due yet: hold, ready to blend into the first sample
            self._anchor = (t_ns, self._p)
            return self._p
        if self.underrun_stops:
            self.counters.underruns += 1  # dry before the end: a controlled stop (module docstring)
            self.raise_fault(Fault.UNDERRUN, t_ns)
            return self._decelerate(dt)
        if not self._dry:  # a drive's hold (CANopen CSP): decelerate, then take up the targets that come again
            self._dry = True
            self.counters.underruns += 1
            self._latch(Fault.UNDERRUN)
        pose = self._decelerate(dt)
        self._anchor = (t_ns, pose)
        return pose

    def _velocity(self) -> np.ndarray:
        """The reference's velocity over the last tick (6,) [m/s, rad/s]: zero after a braked tick or ARM."""
        return (self._p - self._p_before) / self._dt if self._dt > 0 else np.zeros(6)

    def _decelerate(self, dt: float) -> np.ndarray:
        """The reference one tick on, its velocity reduced by the axis accelerations (exactly zero at rest)."""
        v = self._velocity()
        slower = np.sign(v) * np.maximum(np.abs(v) - self._acceleration_limit * dt, 0.0)
        return self._p + slower * dt

    def _stopping(self, t_ns: int, dt: float) -> np.ndarray:
        if self._move is None:
            pose = self._decelerate(dt)
            if np.array_equal(pose, self._p):  # at rest: go home
                duration = shortest_duration(pose, self._velocity_limit, self._acceleration_limit,
                                             self._jerk_limit)
                self._move = Move(t_ns, pose.copy(), np.zeros(6), math.ceil(duration * 1e9))
            return pose
        pose = self._move.at(t_ns)
        if self._arrived(self._move, t_ns):
            self._move = None
            self._set_state(State.ARMED if self._stop_reason is None else State.FAULTED, t_ns)
        return pose

    def _arrived(self, move: Move, t_ns: int) -> bool:
        """Whether ``move`` has ended: reference arrived and the plate in position (a DRIVE fault when overdue;
        a stop's return home ends then, faulted)."""
        if not move.done(t_ns) or move.in_position(self._achieved):
            return move.done(t_ns)
        if move.settle_overdue(t_ns):
            stopping = self.state is State.STOPPING
            self.raise_fault(Fault.DRIVE, t_ns)  # a move in progress becomes a stop
            return stopping
        return False

    def _begin_stop(self, t_ns: int, reason: Fault | None) -> None:
        if reason is not None and reason & (Fault.STREAM_SILENT | Fault.HEARTBEAT_LOST):
            self.counters.watchdog_stops += 1
        if self.state is State.STOPPING:
            self._stop_reason = self._stop_reason or reason
            return
        self._finish_motion(t_ns, Result.CANCELLED)
        self._reset_stream()
        self.limit_levels.clear()
        self._move = None
        self._stop_reason = reason
        self._set_state(State.STOPPING, t_ns)

    def _watchdogs(self, t_ns: int) -> None:
        state = self.state
        now = self.link_time(t_ns)
        if state in _HEARTBEAT_GUARDED and (self._last_heartbeat is None
                                            or now - self._last_heartbeat > self.watchdog_ns):
            self.raise_fault(Fault.HEARTBEAT_LOST, t_ns)
        elif (state is State.STREAMING and self._end_ns is None and self._last_chunk is not None
              and now - self._last_chunk > self.watchdog_ns):
            self.raise_fault(Fault.STREAM_SILENT, t_ns)

    def _finish_motion(self, t_ns: int, result: Result) -> None:
        if self._motion is not None:
            self._events.append(Done(t_ns, self._motion, result))
            self._motion = None

    def _latch(self, fault: Fault) -> None:
        if not self.faults & fault:
            name = fault.name or str(int(fault))
            self.counters.faults_raised[name] = self.counters.faults_raised.get(name, 0) + 1
        self.faults |= fault

    def _set_state(self, new: State, t_ns: int) -> None:
        if new is not self.state:
            self._events.append(StateChange(t_ns, self.state, new))
            self.state = new
