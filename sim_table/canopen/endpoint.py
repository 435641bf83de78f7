"""The emulator's CANopen side: the six CiA 402 leg drives, the plate accelerometers and the overturn detector as
``canopen.LocalNode`` objects on one python-can bus (`sim_table.endpoint`; the master is ``drivers.canopen``).

Listen URL ``canopen://CHANNEL?interface=NAME[&accelerometers=N][&target_delay=S]``: python-can's channel and
interface (``virtual`` within one process, ``udp_multicast`` between processes, only inside a network namespace),
how many of the emulator's sensors are accelerometer nodes (default 1) and the drives' target delay [s] (0x2010,
default :data:`TARGET_DELAY`, within :data:`TARGET_DELAY_RANGE`). Nodes (:mod:`protocols.canopen`): leg drive k =
node k, accelerometer i = node 0x21 + i, the detector = node 0x30.

:class:`CanopenEndpoint` turns cyclic synchronous position into the controller core's setpoint stream: SYNC n is
placed at ``g_n = φ + n·T`` on the controller's clock (T the cycle period 0x1006), the six latched targets become
one pose due at ``g_n +`` the target delay; the drives' CiA 402 states become ARM, START_STREAM, EMERGENCY_STOP and
DISARM; the core's faults, refused targets and following errors become EMCYs and statusword bits; every SYNC is
answered with each drive's TPDO1 (statusword, leg length [µm] at ``g_n −`` :data:`FEEDBACK_DELAY`) and each
accelerometer's specific force [m/s², plate frame]. :meth:`CanopenEndpoint.take` first waits for the bus thread's
backlog (at most :data:`BACKLOG_LIMIT` s). CAN has no authentication: every command counts as signed. It runs in
real time (speed 1); ``loss`` and ``delay`` inject faults.

Every rule with its objects, EMCY codes, counters and measurements: docs/canopen.md §The emulated nodes.
"""

from __future__ import annotations

import heapq
import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import asdict
from typing import Any
from urllib.parse import parse_qs, urlencode, urlsplit, urlunsplit

import can
import canopen
import numpy as np

from analysis.table.model import TableModel, TableModelError
from analysis.table.setpoints import POSITION_ALLOWANCE
from protocols.canopen import (
    LEG_NODE_IDS,
    MASTER_NODE_ID,
    RPDO1,
    Command,
    LegScaling,
    State,
    StatusBit,
    statusword,
    transition,
)
from protocols.canopen import od as drive_od
from protocols.canopen.receive_buffer import ReceiveBacklog, widen_receive_buffer
from protocols.canopen.sensors import (
    ACCELEROMETER_NODE_IDS,
    DETECTOR_NODE_ID,
    EVENT_REPEAT_PERIOD,
    EVENT_REPEATS,
    encode_force,
    event_record,
    load_accelerometer_od,
    load_detector_od,
)
from sim_table.canopen.bus import _HEARTBEAT_COB_ID, _NMT_COB_ID, SYNC_COB_ID, StampingVirtualBus
from sim_table.canopen.counters import BusCounters
from sim_table.canopen.history import HISTORY, Recent
from sim_table.canopen.nodes import FEEDBACK_DELAY, TARGET_DELAY, TARGET_DELAY_RANGE, _Detector, _Drive, _Node, _Sensor
from sim_table.canopen.sync import SERIES_GAP, SyncGrid
from sim_table.controller import BRAKED, ControllerCore, Done, Fault, Refused, Snapshot
from sim_table.controller import Command as CoreCommand
from sim_table.controller import State as CoreState
from sim_table.endpoint import Action, EndpointOptions

BACKLOG_LIMIT = 0.5
"""The longest :meth:`CanopenEndpoint.take` waits for the bus's receive thread [s] (module docstring): half the
default watchdog, so that a receive thread that cannot catch up still leaves the core time to see the silence."""

_LIMITS = Fault.STROKE | Fault.SETPOINT_LIMIT
_EMCY = {Fault.DRIVE: (drive_od.EMCY_DEVICE_HARDWARE, drive_od.ERROR_REGISTER_GENERIC),
         Fault.HEARTBEAT_LOST: (drive_od.EMCY_HEARTBEAT_ERROR,
                                drive_od.ERROR_REGISTER_GENERIC | drive_od.ERROR_REGISTER_COMMUNICATION),
         Fault.STREAM_SILENT: (drive_od.EMCY_SYNC_LOST,
                               drive_od.ERROR_REGISTER_GENERIC | drive_od.ERROR_REGISTER_COMMUNICATION),
         Fault.SETPOINT_REFUSED: (drive_od.EMCY_REFERENCE_LIMIT,
                                  drive_od.ERROR_REGISTER_GENERIC | drive_od.ERROR_REGISTER_DEVICE_PROFILE)}
"""EMCY (code, error register) a drive sends when the core raises a stopping fault."""
_ENABLED = State.OPERATION_ENABLED
_REMOTE, _VOLTAGE = int(StatusBit.REMOTE), int(StatusBit.VOLTAGE_ENABLED)
_FOLLOWS, _LIMIT_ACTIVE = int(StatusBit.FOLLOWS_TARGET), int(StatusBit.INTERNAL_LIMIT_ACTIVE)
_FOLLOWING_ERROR = int(StatusBit.FOLLOWING_ERROR)
_FAULTED = (State.FAULT, State.FAULT_REACTION_ACTIVE)


class CanopenEndpoint:
    """The controller end of a CANopen bus (module docstring): ``interface``/``channel`` of python-can, ``sensors``
    accelerometer nodes, the drives' ``target_delay`` [s] (0x2010), the table model (leg scaling, kinematics),
    ``clock`` host → controller ns, injected ``loss`` and ``delay`` [s] with ``seed``."""

    def __init__(self, url: str, interface: str, channel: str, options: EndpointOptions, sensors: int,
                 target_delay: float = TARGET_DELAY) -> None:
        if not (0.0 <= options.loss < 1.0 and options.delay >= 0.0 and math.isfinite(options.delay)):
            raise ValueError(f"loss must be in [0, 1) and delay >= 0 s, got {options.loss!r}, {options.delay!r}")
        if not 0 <= sensors <= len(ACCELEROMETER_NODE_IDS):
            raise ValueError(f"CANopen carries at most {len(ACCELEROMETER_NODE_IDS)} accelerometers, got {sensors}")
        low, high = TARGET_DELAY_RANGE
        if not (math.isfinite(target_delay) and low <= target_delay <= high):
            raise ValueError(f"target_delay must be in [{low:g}, {high:g}] s, got {target_delay!r}")
        self.url = url
        self.stall_chunks = False
        """Set by the owner to drop every setpoint from then on (injected stalled stream)."""
        self.counters = BusCounters()
        self.target_delay = target_delay
        self.table: TableModel = options.table
        self.clock: Callable[[int], int] = options.clock
        if options.clock(10**12) - options.clock(0) != 10**12:
            raise ValueError("on CANopen the drives follow the master's SYNC in real time: the emulator's speed must "
                             "be 1")
        self.loss = options.loss
        self.delay_ns = round(options.delay * 1e9)
        self._rng = np.random.default_rng(options.seed)
        g = self.table.geometry
        self.scaling = LegScaling(g.leg_min, g.leg_max)
        bus = (StampingVirtualBus(channel=channel, preserve_timestamps=True) if interface == "virtual"
               else can.Bus(interface=interface, channel=channel))
        widen_receive_buffer(bus)  # a stall of this process loses no frame (protocols.canopen.receive_buffer)
        self.network = canopen.Network(bus)
        self.network.NOTIFIER_CYCLE = 0.05  # disconnect() waits up to one cycle
        self._backlog = ReceiveBacklog(bus, canopen.network.MessageListener(self.network))
        self.network.listeners = [self._backlog]  # type: ignore[list-item]  # a Notifier takes any can.Listener
        self.drives = [_Drive(self.network.create_node(leg, drive_od.load_od(leg)), target_delay)
                       for leg in LEG_NODE_IDS]
        self.sensors = [_Sensor(self.network.create_node(node_id, load_accelerometer_od(node_id)))
                        for node_id in ACCELEROMETER_NODE_IDS[:sensors]]
        self.detector = _Detector(self.network.create_node(DETECTOR_NODE_ID, load_detector_od()), options.bodies)
        self._lock = threading.RLock()
        self._legs = Recent(6)
        self._commands = Recent(6)  # the legs' commanded lengths, at the same ticks
        self._answers: deque[tuple[int, float, int, list[int]]] = deque()
        """SYNCs to answer: (measured, stamp, SYNC counter, statuswords)."""
        self._grid: SyncGrid | None = None
        self._enabled = False  # all six drives operation enabled in CSP: the core follows
        self._next_seq = 0
        self._pose = np.zeros(6)  # the last target pose (forward kinematics' next guess)
        self._targets: list[int] = []  # the drives' targets [µm] it is the pose of
        self._last_sample_ns = 0
        self._ending = False  # a stream end is queued: what follows waits for the core to play it
        self._faults = Fault(0)
        self._core_state = CoreState.IDLE
        self._inbox: deque[tuple[int, int, Action]] = deque()  # (due host ns, arrival controller ns, action)
        self._held: list[tuple[int, int, Callable[[], None]]] = []  # delayed work: (due host ns, n, work)
        self._held_count = 0
        self._events: list[tuple[int, int, int, int, int, float, int, int]] = []  # (due, n, copies left, event)
        self.network.subscribe(SYNC_COB_ID, self._on_sync)
        self.network.subscribe(_NMT_COB_ID, self._on_nmt)
        self.network.subscribe(_HEARTBEAT_COB_ID + MASTER_NODE_ID, self._on_master_heartbeat)

    # ----- life cycle -----------------------------------------------------------------------------------

    def start(self) -> None:
        """Every node boots into pre-operational (heartbeats start when the master sets 0x1017), then receiving
        starts: no node answers the master before it has booted (else a master quick enough could configure it
        and start it, and the boot would put it back into pre-operational)."""
        for node in self._nodes():
            node.nmt.state = "PRE-OPERATIONAL"
        self.network.connect()

    def close(self) -> None:
        """Stop the nodes' heartbeats and the receive thread; release the bus."""
        for node in self._nodes():
            node.nmt.stop_heartbeat()
        self.network.disconnect()

    def _nodes(self) -> list[canopen.LocalNode]:
        return [d.node for d in self.drives] + [s.node for s in self.sensors] + [self.detector.node]

    # ----- the bus threads: SYNC, NMT, master heartbeat -------------------------------------------------

    def _on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """A SYNC, handled as arrived at the frame's own time stamp ``timestamp`` [s, wall clock] (module docstring:
        a drive answers at once; this thread may have had to wait for the interpreter)."""
        now = time.monotonic_ns()
        arrived = min(now, now - round((time.time() - timestamp) * 1e9))
        counter = data[0] if len(data) == 1 else 0  # CiA 301: the SYNC counter, when 0x1019 is on
        with self._lock:
            self.counters.sync_handling_max_us = max(self.counters.sync_handling_max_us, (now - arrived) * 1e-3)
            latched = [self._latch(drive) for drive in self.drives]
            if self.delay_ns:
                delay = self.delay_ns
                self._hold(now + delay,
                           lambda: self._sync(arrived + delay, timestamp + delay * 1e-9, counter, latched))
            else:
                self._sync(arrived, timestamp, counter, latched)

    def _latch(self, drive: _Drive) -> tuple[int, int] | None:
        """The (controlword, target) of the drive's last RPDO1; None if its PDOs do not work (not operational, or
        not the RPDO1 map it supports) or none came."""
        if not drive.pdos():
            return None
        rx = drive.node.rpdo[1]
        if rx.timestamp is None or (self.loss and self._rng.random() < self.loss):
            self.counters.rpdos_lost += rx.timestamp is not None
            return None
        setpoint = RPDO1.decode(bytes(rx.data))
        return setpoint.controlword, setpoint.target_position

    def _sync(self, host_ns: int, stamp: float, counter: int, latched: list[tuple[int, int] | None]) -> None:
        """One SYNC, arrived at host time ``host_ns`` (``stamp`` [s, wall clock]) carrying ``counter`` (0: none)
        with the drives' latched RPDOs (module docstring); the TPDOs answering it carry ``stamp`` (and the counter,
        where the master mapped it)."""
        arrival = self.clock(host_ns)
        grid = self._sync_grid()
        slot, new_series = grid.place(arrival, counter)
        self.counters.syncs += 1
        self.counters.sync_series += new_series
        self.counters.sync_delay_max_us = max(self.counters.sync_delay_max_us, (arrival - slot) * 1e-3)
        was_enabled = self._enabled
        actions = [self._step(drive, setpoint) for drive, setpoint in zip(self.drives, latched, strict=True)]
        self._enabled = all(d.state is _ENABLED and d.mode == drive_od.MODE_CYCLIC_SYNCHRONOUS_POSITION
                            for d in self.drives)
        if self._enabled and not was_enabled and not self._ending:
            first = self._next_seq % 2**24
            self._next_seq = first
            self._post(host_ns, arrival, lambda core: self._enable(core, first, arrival))
        if Command.QUICK_STOP in actions:  # also after a fault of the core: the legs brake
            self._post(host_ns, arrival, lambda core: self._emergency_stop(core, arrival))
        elif was_enabled and not self._enabled and any(action is not None for action in actions):
            self._end_stream(host_ns, arrival)
        if self._enabled:
            self._setpoint(host_ns, arrival, slot + _ns(self.target_delay))
        self._feedback(slot, stamp, counter)

    def _sync_grid(self) -> SyncGrid:
        """The grid of the cycle period and SYNC counter the master set (0x1006 [µs], 0x1019; a new grid when
        either changes)."""
        drive = self.drives[0]
        period, overflow = (drive.written(index)
                            for index in (drive_od.COMMUNICATION_CYCLE_PERIOD, drive_od.SYNC_COUNTER_OVERFLOW))
        if self._grid is None or (self._grid.period_ns, self._grid.overflow) != (period * 1000, overflow):
            self._grid = SyncGrid(period * 1000, _ns(SERIES_GAP), overflow)
        return self._grid

    def _step(self, drive: _Drive, setpoint: tuple[int, int] | None) -> Command | None:
        """Step the drive's state machine with its latched controlword; the command if it left operation
        enabled by one (quick stop, or one that disables it)."""
        if setpoint is None:
            return None
        word, drive.target = setpoint
        before = drive.state
        drive.state = transition(before, word, drive.previous_word)
        drive.previous_word = word
        if before is State.FAULT and drive.state is not State.FAULT:
            drive.following_error_latched = False
            self._emcy(drive, 0, 0)  # error reset
        if before is _ENABLED and drive.state is not _ENABLED:
            return Command.QUICK_STOP if drive.state is State.QUICK_STOP_ACTIVE else Command.DISABLE_OPERATION
        return None

    def _setpoint(self, host_ns: int, arrival: int, due: int) -> None:
        if self.stall_chunks:
            self.counters.chunks_stalled += 1
            return
        targets = [d.target for d in self.drives]
        if targets != self._targets:  # held targets (an armed table at rest) need no forward kinematics
            self._targets = targets
            pose = self._target_pose(np.array(self.scaling.lengths(targets)))
            if isinstance(pose, str):  # the core refuses it and stops; the pose stays the last one played
                problem = pose
                seq = self._next_seq
                self._next_seq = (seq + 1) % 2**32
                self.counters.targets_refused += 1
                self._post(host_ns, arrival, lambda core: core.refuse_chunk(seq, problem, arrival))
                return
            self._pose = pose
        seq, pose = self._next_seq, self._pose.copy()
        self._next_seq = (seq + 1) % 2**32
        self._last_sample_ns = due
        self.counters.chunks_sent += 1
        period = self._sync_grid().period_ns
        self._post(host_ns, arrival, lambda core: core.chunk(seq, due, period, pose[None, :], False, True, arrival))

    def _target_pose(self, lengths: np.ndarray) -> np.ndarray | str:
        """The pose of the six drives' targets, as leg ``lengths`` (6,) [m] (forward kinematics from the last one;
        the core then checks it as any setpoint), or why they have none (a text): a target outside its leg's stroke
        (0x607D, with ``analysis.table.setpoints.POSITION_ALLOWANCE``), or lengths no pose has."""
        g = self.table.geometry
        low, high = g.leg_min - POSITION_ALLOWANCE, g.leg_max + POSITION_ALLOWANCE
        outside = np.flatnonzero((lengths < low) | (lengths > high))
        if len(outside):
            leg = int(outside[0])
            return (f"leg {leg + 1} target {lengths[leg]:.6f} m outside its stroke [{g.leg_min:.4f}, "
                    f"{g.leg_max:.4f}] m")
        try:
            return self.table.pose_from_leg_lengths(lengths, guess=self._pose, tol=1e-7)
        except TableModelError as exc:
            return f"leg targets {', '.join(f'{v:.6f}' for v in lengths)} m: no pose ({exc})"

    def _end_stream(self, host_ns: int, arrival: int) -> None:
        """The drives were disabled (at rest): end the stream at the last target; once the core played it,
        :meth:`_after_end` disarms it (or starts a new stream if the drives were enabled again meanwhile)."""
        seq, pose, due = self._next_seq, self._pose.copy(), max(self._last_sample_ns, arrival) + 1
        self._next_seq = (seq + 1) % 2**32
        self._ending = True
        period = self._sync_grid().period_ns
        self._post(host_ns, arrival, lambda core: core.chunk(seq, due, period, pose[None, :], True, True, arrival))

    def _feedback(self, slot: int, stamp: float, counter: int) -> None:
        """Answer the SYNC in ``slot`` (stamped ``stamp``, carrying ``counter``): each drive's statusword as of now,
        positions and accelerations as of ``slot −`` the feedback delay — at once if the physics has computed that
        instant, else when it has (:meth:`add_legs`, :meth:`add_accel`; the TPDOs keep the SYNC's stamp and
        counter)."""
        follows = self._enabled and not self.stall_chunks and self._core_state is CoreState.STREAMING
        flags = _REMOTE | (_LIMIT_ACTIVE if self._faults & _LIMITS else 0)
        words = [statusword(d.state, flags | (_VOLTAGE if d.state is not State.SWITCH_ON_DISABLED else 0)
                            | (_FOLLOWS if follows and d.state is _ENABLED else 0)
                            | (_FOLLOWING_ERROR if d.following_error_latched else 0)) for d in self.drives]
        if len(self._answers) >= HISTORY:  # the physics stopped (the emulator is closing)
            self._answers.popleft()
            self.counters.answers_dropped += 1
        self._answers.append((slot - _ns(FEEDBACK_DELAY), stamp, counter, words))
        self._answer()
        self.counters.feedback_deferred += bool(self._answers)  # this one waits for the physics

    def _answer(self) -> None:
        """Send the waiting answers whose instant the physics has computed, in order."""
        g = self.table.geometry
        while self._answers:
            measured, stamp, counter, words = self._answers[0]
            fed = [s.samples.newest_ns for s in self.sensors if s.samples.newest_ns is not None]
            if self._legs.newest_ns is None or min([self._legs.newest_ns, *fed]) < measured:
                return
            self._answers.popleft()
            kept = [s.samples.oldest_ns for s in self.sensors if s.samples.oldest_ns is not None]
            if max([self._legs.oldest_ns or 0, *kept]) > measured:  # its instant has left the history
                self.counters.answers_forgotten += 1
                continue
            legs = np.clip(self._legs.at(measured), g.leg_min, g.leg_max)
            errors = np.rint((self._commands.at(measured) - legs) * 1e6).astype(int).tolist()
            for drive, word, length, error in zip(self.drives, words, legs.tolist(), errors, strict=True):
                drive.position = self.scaling.position(length)
                drive.following_error = error
                drive.flags = word & ~0x6F
                self._transmit(drive, (word, drive.position), stamp, counter)
            for sensor in self.sensors:
                if sensor.samples.newest_ns is not None:
                    sensor.sample = encode_force(sensor.samples.at(measured))
                    self.counters.accel_samples_sent += self._transmit(sensor, sensor.sample, stamp, counter)

    def _watch_following(self, lengths: np.ndarray, commanded: np.ndarray) -> None:
        """Each enabled drive watches its following error at every tick of the physics while the core streams, as a
        drive's servo loop does whatever the SYNCs do (module docstring): the first tick beyond its window trips it."""
        if self._core_state is not CoreState.STREAMING:
            return
        g = self.table.geometry
        errors = np.rint((commanded - np.clip(lengths, g.leg_min, g.leg_max)) * 1e6).astype(np.int64)
        for drive, error in zip(self.drives, errors.T, strict=True):
            window = drive.following_error_window
            if drive.state is not _ENABLED or window is None:
                continue
            beyond = np.flatnonzero(np.abs(error) > window)
            watched = error[:beyond[0] + 1] if beyond.size else error
            self.counters.following_error_max_um = max(self.counters.following_error_max_um,
                                                       int(np.abs(watched).max()))
            if beyond.size:
                self._following_error(drive)

    def _following_error(self, drive: _Drive) -> None:
        """The drive's following error passed its window: bit 13 (shown from the next SYNC's statusword), fault
        reaction, EMCY 0x8611, a DRIVE fault of the core (which stops the table)."""
        drive.state = State.FAULT_REACTION_ACTIVE
        drive.following_error_latched = True
        self.counters.following_errors += 1
        self._emcy(drive, drive_od.EMCY_FOLLOWING_ERROR, drive_od.ERROR_REGISTER_GENERIC)
        now = time.monotonic_ns()
        arrival = self.clock(now)
        self._post(now, arrival, lambda core: core.raise_fault(Fault.DRIVE, arrival))

    def _transmit(self, device: _Node, values: tuple[int, ...], stamp: float | None = None, counter: int = 0) -> bool:
        """Send the node's TPDO1 carrying ``values`` (and ``counter``, the answered SYNC's, where the master mapped
        it) stamped ``stamp`` (default now); whether it went out (PDOs working, TPDO1 enabled, not lost)."""
        if not device.pdos() or not device.node.tpdo[1].enabled:
            return False
        assert device.transmits is not None
        payload = device.transmits.encode((*values, counter) if device.counted() else values)
        return self._send(device.node.tpdo[1].cob_id, payload, stamp)

    def _on_nmt(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """After the nodes took an NMT command: PDO maps are read again once operational; a drive that stops being
        operational while enabled quick-stops (the legs brake)."""
        now = time.monotonic_ns()
        with self._lock:
            for device in [*self.drives, *self.sensors, self.detector]:
                device.mapped = False
            for drive in self.drives:
                if not drive.operational and drive.state is _ENABLED:
                    drive.state = State.QUICK_STOP_ACTIVE
            if self._enabled and not all(d.operational for d in self.drives):
                self._enabled = False
                arrival = self.clock(now)
                self._post(now, arrival, lambda core: self._emergency_stop(core, arrival))

    def _on_master_heartbeat(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """The master's heartbeat, arrived at the frame's time stamp: the core's host heartbeat."""
        now = time.monotonic_ns()
        due = min(now, now - round((time.time() - timestamp) * 1e9)) + self.delay_ns
        arrival = self.clock(due)
        with self._lock:
            self.counters.master_heartbeats += 1
            self._post(due, arrival, lambda core: core.heartbeat(arrival))

    # ----- actions on the core (the emulator's tick thread) ---------------------------------------------

    def _post(self, host_ns: int, arrival: int, action: Action) -> None:
        self._inbox.append((host_ns, arrival, action))

    @staticmethod
    def _enable(core: ControllerCore, first: int, arrival: int) -> None:
        if core.state is not CoreState.STREAMING:
            core.command(CoreCommand.ARM, (), True, arrival)
            core.command(CoreCommand.START_STREAM, (float(first),), True, arrival)

    @staticmethod
    def _emergency_stop(core: ControllerCore, arrival: int) -> None:
        if core.state not in BRAKED:
            core.command(CoreCommand.EMERGENCY_STOP, (), True, arrival)

    def _after_end(self, core: ControllerCore, arrival: int) -> None:
        with self._lock:
            if not self._ending or core.state is CoreState.STREAMING:
                return  # done already, or the end of the stream is not played yet
            self._ending = False
            if self._enabled:
                first = self._next_seq % 2**24
                self._next_seq = first
                self._enable(core, first, arrival)
            elif core.state is CoreState.ARMED:
                core.command(CoreCommand.DISARM, (), True, arrival)

    def take(self, now: int) -> list[tuple[int, Action]]:
        """Messages due by host time ``now`` [ns] as (arrival controller time [ns], action on the core), once the
        receive thread has handled every frame received (module docstring)."""
        waited, cleared = self._backlog.wait(BACKLOG_LIMIT)
        with self._lock:
            if waited > 0.0:
                self.counters.backlog_waits += 1
                self.counters.backlog_wait_max_us = max(self.counters.backlog_wait_max_us, waited * 1e6)
            self.counters.backlog_limit_reached += not cleared
            taken = []
            while self._inbox and self._inbox[0][0] <= now:
                _, arrival, action = self._inbox.popleft()
                taken.append((arrival, action))
            if self._ending:
                arrival = self.clock(now)
                taken.append((arrival, lambda core: self._after_end(core, arrival)))
            return taken

    def command_done(self, done: Done) -> None:
        """Nothing the CANopen side asks of the core answers IN_PROGRESS: no final answer to send."""

    def chunk_refused(self, refused: Refused) -> None:
        """A refused target: the drives say it with the EMCY of the stopping fault ``SETPOINT_REFUSED``
        (:data:`~protocols.canopen.od.EMCY_REFERENCE_LIMIT`, sent by :meth:`send_status`); counted here."""
        self.counters.refusals += 1

    def send_status(self, snap: Snapshot) -> None:
        """The core's state and faults: its stopping faults become drive faults with EMCY (module docstring)."""
        with self._lock:
            raised = snap.faults & ~self._faults
            self._faults, self._core_state = snap.faults, snap.state
            braked = snap.state in BRAKED
            for fault, (code, register) in _EMCY.items():
                if raised & fault:
                    concerned = self.drives[:1] if fault is Fault.DRIVE else self.drives
                    if fault is Fault.DRIVE and any(d.state in _FAULTED for d in self.drives):
                        concerned = []  # a drive's own fault (following error) raised it: no other drive faults
                    for drive in concerned:
                        if drive.state not in _FAULTED:
                            drive.state = State.FAULT if braked else State.FAULT_REACTION_ACTIVE
                            self._emcy(drive, code, register)
            if braked:
                for drive in self.drives:
                    if drive.state is State.FAULT_REACTION_ACTIVE:
                        drive.state = State.FAULT

    def _emcy(self, drive: _Drive, code: int, register: int) -> None:
        self.counters.emcy_sent += 1
        self._send(drive.node.emcy.cob_id, canopen.emcy.EMCY_STRUCT.pack(code, register, b""))

    # ----- what the emulator loop hands over --------------------------------------------------------------

    def add_legs(self, t_start_ns: int, spacing_ns: int, lengths: np.ndarray, commanded: np.ndarray) -> None:
        """The legs' true and ``commanded`` lengths [m] (k, 6) at ticks ``t_start_ns + j·spacing_ns`` [ns, controller
        time]."""
        with self._lock:
            self._commands.extend(t_start_ns, spacing_ns, commanded)
            self._legs.extend(t_start_ns, spacing_ns, lengths)
            self._watch_following(lengths, commanded)
            self._answer()

    def add_accel(self, sensor_id: int, t_start_ns: int, spacing_ns: int, samples: np.ndarray) -> None:
        """A sensor's next samples (n, 3) [m/s²], the first at ``t_start_ns``; sent one per SYNC (accelerometer
        nodes carry the first sensors; a sensor beyond them is not on the bus)."""
        if sensor_id < len(self.sensors):
            with self._lock:
                self.sensors[sensor_id].samples.extend(t_start_ns, spacing_ns, samples)
                self._answer()

    def flush_accel(self) -> None:
        """Nothing waits: every sample an accelerometer sends goes out on its SYNC."""

    def add_tilt(self, body_id: int, t_start_ns: int, spacing_ns: int, angles: np.ndarray) -> None:
        """Nothing is sent: the bus has no room for tilt telemetry (``protocols/canopen/bus_load.py``); the overturn
        detector reports overturns only."""

    def flush_tilt(self) -> None:
        """Nothing waits: no tilt sample is sent."""

    def send_overturn(self, event_id: int, body_id: int, direction: int, tilt: float, t_ns: int) -> None:
        """An overturn event: sent now and again :data:`EVENT_REPEATS` times, each copy with its age."""
        with self._lock:
            self.counters.overturn_events += 1
            self._held_count += 1
            heapq.heappush(self._events, (time.monotonic_ns(), self._held_count, EVENT_REPEATS + 1, event_id,
                                          body_id, tilt, t_ns, direction))
            self._send_events(time.monotonic_ns())

    def _send_events(self, now: int) -> None:
        detector = self.detector
        while self._events and self._events[0][0] <= now:
            due, n, left, event_id, body_id, tilt, t_ns, direction = heapq.heappop(self._events)
            stamp, sent = time.time(), time.monotonic_ns()  # the frame's stamp and its age read together: a
            age = max(0, self.clock(sent) - t_ns)  # thread that waits for its turn in between must not age it
            detector.record = event_record(event_id, body_id, direction, tilt, age)
            self.counters.overturn_messages_sent += self._transmit(detector, detector.record, stamp)
            if left > 1:
                heapq.heappush(self._events, (due + round(EVENT_REPEAT_PERIOD * 1e9), n, left - 1, event_id,
                                              body_id, tilt, t_ns, direction))

    def service(self, now: int, state: CoreState) -> None:
        """Periodic duties at host time ``now`` [ns]: event repetitions, delayed SYNCs and frames."""
        with self._lock:
            self._send_events(now)
            while self._held and self._held[0][0] <= now:
                heapq.heappop(self._held)[2]()

    # ----- sending -----------------------------------------------------------------------------------------

    def _hold(self, due: int, work: Callable[[], None]) -> None:
        self._held_count += 1
        heapq.heappush(self._held, (due, self._held_count, work))

    def _send(self, cob_id: int, data: bytes, stamp: float | None = None) -> bool:
        """Send one frame stamped ``stamp`` [s, wall clock; default now] through the injected loss and delay;
        whether it was not lost. (On the virtual bus the receiver sees the stamp; other interfaces stamp frames
        when they receive them.)"""
        if self.loss and self._rng.random() < self.loss:
            self.counters.frames_not_sent += 1
            return False
        frame = can.Message(arbitration_id=cob_id, data=data, is_extended_id=False,
                            timestamp=time.time() if stamp is None else stamp)
        if self.delay_ns:
            frame.timestamp += self.delay_ns * 1e-9
            self._hold(time.monotonic_ns() + self.delay_ns, lambda: self._put(frame))
        else:
            self._put(frame)
        return True

    def _put(self, frame: can.Message) -> None:
        with self.network.send_lock:
            bus = self.network.bus
            if bus is None:
                raise can.CanOperationError("the emulated table's CANopen network is closed: no frame is sent")
            bus.send(frame)
        self.counters.frames_sent += 1

    def counters_dict(self) -> dict[str, Any]:
        return asdict(self.counters)


def _ns(seconds: float) -> int:
    return round(seconds * 1e9)


def open_endpoint(url: str, options: EndpointOptions) -> CanopenEndpoint:
    """The endpoint for ``canopen://CHANNEL?interface=NAME[&accelerometers=N][&target_delay=S]`` —
    `sim_table.endpoint`'s factory.

    ``accelerometers`` (default 1) accelerometer nodes carry the emulator's first sensors (more than one does
    not fit 1 Mbit/s at 500 Hz: :mod:`protocols.canopen.bus_load`); ``target_delay`` [s] the drives' 0x2010 (default
    :data:`TARGET_DELAY`; the master reads it and sends each target that much ahead: a host that may stall longer
    than 60 ms — the tests' one interpreter for master and emulator on a busy machine — sets more). The endpoint's
    URL, the master's, leaves ``target_delay`` out (a property of the drives, not of the bus)."""
    parts = urlsplit(url)
    query = {key: values[-1] for key, values in parse_qs(parts.query).items()}
    unknown = set(query) - {"interface", "accelerometers", "target_delay"}
    if parts.scheme != "canopen" or not parts.netloc or "interface" not in query or unknown:
        raise ValueError(f"--listen {url!r}: expected canopen://CHANNEL?interface=NAME[&accelerometers=N]"
                         "[&target_delay=S]" + (f" (unknown {', '.join(sorted(unknown))})" if unknown else ""))
    try:
        sensors = int(query.get("accelerometers", "1"))
        target_delay = float(query.get("target_delay", TARGET_DELAY))
    except ValueError:
        raise ValueError(f"--listen {url!r}: accelerometers must be an integer, target_delay a number of seconds") \
            from None
    bus_query = urlencode({key: value for key, value in query.items() if key != "target_delay"})
    bus_url = urlunsplit((parts.scheme, parts.netloc, parts.path, bus_query, ""))
    return CanopenEndpoint(bus_url, query["interface"], parts.netloc, options, sensors, target_delay)
