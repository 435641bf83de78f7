"""The table controller over CANopen: ``open_table("canopen://CHANNEL?interface=NAME")``.

This host is the **CANopen master** of the table: six CiA 402 leg drives in cyclic synchronous position mode (CSP),
the plate accelerometers and the overturn detector (node ids, EDS and PDO maps in :mod:`protocols.canopen`). On
CANopen the table controller of ``docs/table-controller.md`` is this master: it plays every motion itself and
sends the drives a leg length per cycle.

**URL and options.** ``canopen://CHANNEL?interface=NAME[&bitrate=N][&rate=HZ][&accelerometers=N]`` — python-can's
channel and interface (``virtual`` within one process; ``udp_multicast`` across processes, only inside a network
namespace: elsewhere the multicast group leaves the host), the bus bitrate [bit/s] (default 1 Mbit/s), the SYNC
(setpoint) rate [Hz] (default 500) and the number of accelerometer nodes (default 1); the same names as keyword
options of :func:`~drivers.controller.open_table` (a keyword wins). The rate must fit the bus: the worst-case load
of a cycle (SYNC, RPDO1 + TPDO1 per drive, a TPDO per accelerometer) must stay within 80 % of the bitrate
(:func:`protocols.canopen.check_bus_load`); 1 kHz of six drives needs 143.5 % of 1 Mbit/s and is refused with the
numbers (:class:`~protocols.canopen.BusLoadError`, a ValueError). 500 Hz with one accelerometer takes 77.5 %.

**Connecting.** NMT pre-operational; by SDO each drive gets CSP (0x6060 = 8, checked in 0x6061), the cycle period
0x1006, the software position limits 0x607D and the speed limit 0x607F of the table model's legs, its following
error window 0x6065 (:data:`FOLLOWING_ERROR_LAG` at the legs' top speed), a heartbeat
every :data:`HEARTBEAT_PERIOD` (0x1017), the master's heartbeat to consume (0x1016: :data:`CONSUMER_TIME`) and its
PDO maps (RPDO1 controlword + target, TPDO1 statusword + position actual); the master reads its target delay
(0x2010) and feedback delay (0x2011). The accelerometers get their SYNC TPDO and heartbeat (sample delay 0x2101),
the detector its event TPDO and heartbeat. Then NMT operational, the cycle starts, and :meth:`CanopenTable.connect`
returns with the first status once every node's heartbeat reports *operational* (a node whose heartbeat after the
start command still reports another state — it missed the command, or booted again — is sent it again; ARM is
refused while a drive is not operational: a drive that rebooted has lost its configuration, connect again).

**The cycle** (one thread, sleeping to absolute deadlines ``t_n = t_0 + n·T``): the master takes the feedback,
checks faults and heartbeats, advances its reference to ``t_n + D`` (D the drives' target delay: a target latched
at SYNC n is reached then; one cycle for a CSP drive), clips it to the table's envelope (SETPOINT_LIMIT), computes
the six leg lengths by inverse kinematics (clipped to the stroke: STROKE), writes each drive's RPDO1 (controlword,
target in µm) and then sends SYNC; its own heartbeat (COB-ID 0x77F) every :data:`MASTER_HEARTBEAT_PERIOD`. A late
cycle is sent late, never skipped (the drives count SYNCs); if it comes later than ``D − T`` the drives ran out of
setpoints: an underrun (``UNDERRUN``).

**The table's behaviour on CiA 402 and CSP:**

================  ================================================================================================
ARM               each drive through its CiA 402 states to *operation enabled* (fault reset on a rising bit 7,
                  shutdown, switch on, enable operation), its target held at its actual position; ``armed`` when
                  all six are enabled, the reference then the measured pose (forward kinematics). Clears the
                  latched faults. Refused while a drive's heartbeat is missing.
DISARM            disable operation on all six (only armed or faulted) → ``idle`` when none is enabled.
HOME, SET_TILT    moves the master plays: quintic ``10τ³ − 15τ⁴ + 6τ⁵`` as in ``rig.drive.tilt``, as short as the axis
                  velocity, acceleration and (rotations) tilt jerk limits allow. A move (also a stop's return
                  home) ends when its reference has arrived and the newest measured pose is within
                  ``analysis.table.moves.IN_POSITION`` of its end; not in position ``SETTLE_TIME_NS`` later → DRIVE.
START_STREAM      :meth:`CanopenTable.stream`: the master interpolates the trajectory at each ``t_n + D`` (from the
                  pose held when it was called, blending into the first sample ``lead`` s later; ``lead`` must
                  exceed D + T).
STOP              the master decelerates its reference at the axis accelerations to rest, then moves home; armed.
EMERGENCY_STOP    the quick stop controlword to all six in one cycle (they latch it at the same SYNC): the legs stop
                  at once, no return home; only ARM leaves ``emergency_stopped``.
faults            an EMCY (0x8130 → HEARTBEAT_LOST: the drives lost this master's heartbeat; 0x8700 →
                  STREAM_SILENT: their setpoints stopped; other codes → DRIVE, among them 0x8611, a leg's
                  following error beyond 0x6065; the fault event names the node and code that raised it:
                  :attr:`~drivers.controller.FaultEvent.sources`), a drive's statusword in fault, a
                  drive's heartbeat older than :data:`NODE_CONSUMER_TIME` (DRIVE) or statusword bit 11 (internal
                  limit: SETPOINT_LIMIT) latch a fault. DRIVE, HEARTBEAT_LOST and STREAM_SILENT stop the table: a
                  hexapod cannot make a coordinated move without one of its legs, so the master quick-stops every
                  drive (the doc's "decelerate, then home" is beyond a CSP master then); ``stopping`` while a
                  drive's fault reaction runs (the table's own, e.g. the emulator's return home), then ``faulted``.
================  ================================================================================================

**Time.** On CANopen the controller is this master: controller time is its clock (host monotonic ns). A frame
answers the last SYNC sent before its time stamp (python-can's: the receive time, or on the ``virtual`` bus the
sender's); a status reports the pose of the newest SYNC all six drives answered, measured at that SYNC's time minus
the feedback delay; an accelerometer sample is from its SYNC's time minus the sample delay, so a sensor's count is
duration × SYNC rate; an overturn happened its age before its frame.

**Authentication.** CAN has none and neither does CANopen: this transport relies on the bus being a private cable
between the lab host and the table (nothing else attached, not bridged to a network). Nothing is signed, and the
controller (the emulator too) refuses no command for a signature: ``refused_commands`` stays 0.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any
from urllib.parse import parse_qs, urlsplit

import can
import canopen
import numpy as np

from analysis.table.model import TableModel
from analysis.table.moves import Move, axis_limits
from drivers.controller import (
    STATUS_TIMEOUT,
    STOPPED_STATES,
    TILT_AXES,
    AccelBatch,
    CommandFailedError,
    CommandRejectedError,
    Detection,
    FaultSource,
    StreamAbortedError,
    StreamReport,
    TableController,
    TableError,
    TableStatus,
    TableTimeoutError,
    finite_poses,
    register_scheme,
    sample_spacing,
    sleep_until,
)
from protocols.canopen import (
    DEFAULT_RATE_HZ,
    LEG_NODE_IDS,
    MASTER_NODE_ID,
    RPDO1,
    TPDO1,
    Command,
    LegScaling,
    Setpoint,
    State,
    StatusBit,
    check_bus_load,
    command_towards_operation,
    configure,
    controlword,
    cycle_period_us,
    decode_statusword,
    heartbeat_consumer_entry,
    velocity_increments,
)
from protocols.canopen import od as drive_od
from protocols.canopen.sensors import (
    ACCEL_TPDO1,
    ACCELEROMETER_NODE_IDS,
    DETECTOR_NODE_ID,
    EVENT_TPDO1,
    SAMPLE_DELAY,
    decode_force,
    event_age_ns,
    event_tilt,
    load_accelerometer_od,
    load_detector_od,
)

DEFAULT_BITRATE = 1_000_000
"""Bus bitrate [bit/s] unless the URL or an option says otherwise."""

HEARTBEAT_PERIOD = 0.05
"""Heartbeat period of every node [s] (0x1017 in ms)."""

MASTER_HEARTBEAT_PERIOD = 0.02
"""The master's heartbeat period [s]: five within the drives' consumer time."""

CONSUMER_TIME = 0.1
"""The drives' consumer time of the master's heartbeat [s] (0x1016): without one for this long they stop the table."""

FOLLOWING_ERROR_LAG = 0.010
"""How far behind its command a leg may be, as time at the legs' top speed [s]: each drive's following error window
0x6065 is this × the table model's leg speed (9000 µm at 0.9 m/s). A leg that follows trails its command by τ·v (a
first-order lag, τ = 5 ms for the table's drives), by at most 4.5 mm at top speed: the window is twice that bound.
A leg that stops while moving at v trips it (9 mm − τ·v)/v later: 5 ms at top speed, 85 ms at 0.1 m/s."""

NODE_CONSUMER_TIME = 0.2
"""The master's consumer time of each node's heartbeat [s] (four periods): older, the node is lost."""

STATUS_RATE = 50.0
"""Statuses per second (and one at every state change)."""

ACCEL_BATCH = 25
"""Accelerometer samples per published batch."""

STATUS_WAIT = 0.1
"""After a command, wait up to this long [s] for the status that shows it."""

SDO_TIMEOUT = 1.0
"""How long [s] an SDO request waits for its answer (once; the configuration at connect is the only SDO traffic)."""

SYNC_COB_ID = 0x80
_HEARTBEAT_COB_ID = 0x700
_NMT_OPERATIONAL = 0x05

FAULT_ORDER = ("DRIVE", "STROKE", "STREAM_SILENT", "HEARTBEAT_LOST", "UNSIGNED_COMMAND", "SETPOINT_LIMIT",
               "CHUNK_GAP", "UNDERRUN")
"""Fault names in the order of their bits (``docs/table-controller.md``; the same as MAVLink's)."""

_STOPPING_FAULTS = frozenset({"DRIVE", "HEARTBEAT_LOST", "STREAM_SILENT"})
_EMCY_FAULTS = {drive_od.EMCY_HEARTBEAT_ERROR: "HEARTBEAT_LOST", drive_od.EMCY_SYNC_LOST: "STREAM_SILENT"}
"""EMCY codes that name their fault; every other code (except error reset, 0x00xx) is a DRIVE fault."""
_MOVING = frozenset({"homing", "tilting", "streaming"})
_DRIVING = frozenset({"armed", "homing", "tilting", "streaming"})  # the drives follow the reference
_FAULTY = frozenset({State.FAULT, State.FAULT_REACTION_ACTIVE})
_QUERY = ("interface", "bitrate", "rate", "accelerometers")


# ----- the motions the master plays ----------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A stream: ``poses`` (N, 6) due at ``t_start_ns + k·spacing_ns``, blended into linearly from the pose
    ``anchor`` held at ``anchor_ns``."""

    anchor_ns: int
    anchor: np.ndarray
    t_start_ns: int
    spacing_ns: int
    poses: np.ndarray

    @property
    def t_end_ns(self) -> int:
        return self.t_start_ns + (len(self.poses) - 1) * self.spacing_ns

    def due(self, t_ns: int) -> int:
        """Samples due by ``t_ns``."""
        return min(len(self.poses), max(0, (t_ns - self.t_start_ns) // self.spacing_ns + 1))

    def at(self, t_ns: int) -> np.ndarray:
        if t_ns < self.t_start_ns:
            share = (t_ns - self.anchor_ns) / (self.t_start_ns - self.anchor_ns)
            return self.anchor + (self.poses[0] - self.anchor) * max(0.0, share)
        k = (t_ns - self.t_start_ns) / self.spacing_ns
        if k >= len(self.poses) - 1:
            return self.poses[-1].copy()
        i = int(k)
        return self.poses[i] + (self.poses[i + 1] - self.poses[i]) * (k - i)


# ----- the nodes as the master sees them ------------------------------------------------------------------


class _Link:
    """What the master knows of one node: its ``RemoteNode``, last heartbeat [host ns], the NMT state that heartbeat
    reported, and EMCYs."""

    def __init__(self, node: canopen.RemoteNode) -> None:
        self.node = node
        self.heartbeat_ns: int | None = None
        self.nmt_state: int | None = None
        self.started_ns = 0  # when the master last sent it the NMT start command [host ns]
        self.emcy: list[tuple[int, int]] = []  # (code, host ns)
        node.nmt.add_heartbeat_callback(self._beat)

    def _beat(self, state: int) -> None:
        self.heartbeat_ns = time.monotonic_ns()
        self.nmt_state = state

    def heartbeat_age(self, now: int) -> float | None:
        """Seconds since its last heartbeat (None before the first)."""
        return None if self.heartbeat_ns is None else (now - self.heartbeat_ns) * 1e-9


class _DriveLink(_Link):
    """A leg drive: its last statusword and position, the controlword last sent."""

    def __init__(self, node: canopen.RemoteNode) -> None:
        super().__init__(node)
        self.statusword: int | None = None
        self.position = 0
        self.word = 0

    @property
    def state(self) -> State | None:
        return None if self.statusword is None else decode_statusword(self.statusword)


class _SensorLink(_Link):
    """An accelerometer: the samples waiting to be published as one batch."""

    def __init__(self, node: canopen.RemoteNode, sensor_id: int) -> None:
        super().__init__(node)
        self.sensor_id = sensor_id
        self.pending: list[tuple[int, tuple[float, float, float]]] = []  # (SYNC index, force)
        self.next_index: int | None = None
        self.seq = 0
        self.lost = 0


def _query(url: str) -> tuple[str, dict[str, str]]:
    parts = urlsplit(url)
    query = {key: values[-1] for key, values in parse_qs(parts.query).items()}
    unknown = sorted(set(query) - set(_QUERY))
    if parts.scheme != "canopen" or not parts.netloc or unknown:
        raise ValueError(f"table URL {url!r}: expected canopen://CHANNEL?interface=NAME[&bitrate=N][&rate=HZ]"
                         f"[&accelerometers=N]" + (f" (unknown {', '.join(unknown)})" if unknown else ""))
    return parts.netloc, query


class CanopenTable(TableController):
    """The table's CANopen master on ``canopen://CHANNEL?interface=NAME`` (module docstring).

    Options (keywords, or the URL's query): ``interface``, ``bitrate`` [bit/s], ``rate`` [Hz] of SYNC,
    ``accelerometers`` (nodes 0x21…); ``detector`` whether the overturn detector (node 0x30) is on the bus;
    ``table`` the table model (limits, geometry); ``connect_timeout`` and ``command_timeout`` [s] (ARM and DISARM
    wait for the drives' states). Raises :class:`~protocols.canopen.BusLoadError` when the rate does not fit.
    """

    def __init__(self, url: str, *, interface: str | None = None, bitrate: int | None = None,
                 rate: float | None = None, accelerometers: int | None = None, detector: bool = True,
                 table: TableModel | None = None, connect_timeout: float = 5.0, command_timeout: float = 2.0) -> None:
        super().__init__(url)
        self.channel, query = _query(url)
        try:
            self.interface = interface or query["interface"]
            self.bitrate = int(bitrate if bitrate is not None else query.get("bitrate", DEFAULT_BITRATE))
            self.rate = float(rate if rate is not None else query.get("rate", DEFAULT_RATE_HZ))
            count = int(accelerometers if accelerometers is not None else query.get("accelerometers", 1))
        except KeyError:
            raise ValueError(f"table URL {url!r}: the python-can interface is missing (?interface=NAME)") from None
        if not 0 <= count <= len(ACCELEROMETER_NODE_IDS):
            raise ValueError(f"accelerometers must be 0..{len(ACCELEROMETER_NODE_IDS)}, got {count}")
        self.bus_load = check_bus_load(self.rate, len(LEG_NODE_IDS), self.bitrate, accelerometers=count)
        """Worst-case share of the bitrate the cycle takes."""
        self.period_ns = cycle_period_us(self.rate) * 1000
        self.table = table or TableModel()
        geometry = self.table.geometry
        self.scaling = LegScaling(geometry.leg_min, geometry.leg_max)
        lim = self.table.limits
        self._bounds = np.array([lim.surge.displacement, lim.lateral.displacement, lim.heave.displacement,
                                 lim.tilt.angle, lim.tilt.angle, math.inf])
        self._acceleration = axis_limits(self.table)[1]
        self.accelerometer_count = count
        self.detector = detector
        self.connect_timeout = connect_timeout
        self.command_timeout = command_timeout
        self.target_delay_ns = 0
        """The drives' target delay (0x2010) [ns]: a target latched at a SYNC is reached this long after it."""
        self.feedback_delay_ns = 0
        """The drives' feedback delay (0x2011) [ns]: a TPDO's position was measured this long before its SYNC."""
        self.sample_delay_ns = 0
        """The accelerometers' sample delay (0x2101) [ns]."""
        self._network: canopen.Network | None = None
        self._drives: list[_DriveLink] = []
        self._sensors: list[_SensorLink] = []
        self._detector: _Link | None = None
        self._lock = threading.RLock()
        self._closing = threading.Event()
        self._thread: threading.Thread | None = None
        self._failure: BaseException | None = None
        # the master's controller state (under _lock)
        self._state = "idle"
        self._faults: set[str] = set()
        self._stop_reason: str | None = None  # the fault that is stopping the table (None: STOP)
        self._arming = False
        self._pose = np.zeros(6)  # the reference, for time _tau
        self._velocity = np.zeros(6)
        self._tau = 0
        self._move: Move | None = None
        self._trajectory: Trajectory | None = None
        self._homing_after_stop = False
        self._cycle_index = 0
        self._next_deadline = 0
        self._arrived_ns = 0  # time stamp [ns, controller time] of the status that showed the last move in position
        self._underruns = 0
        self._dry = False
        self._lateness: list[int] | None = None  # per cycle during a stream [ns]
        self._stream_cycles = 0
        self._published_state = ""
        self._status_owed = False
        # feedback (under _lock)
        self._syncs: deque[tuple[float, int, int]] = deque(maxlen=512)  # (wall time sent, index, deadline ns)
        self._frames: dict[int, dict[int, int]] = {}  # SYNC index -> {leg index: position}
        self._measured = np.zeros(6)
        self._played: Trajectory | None = None  # the last trajectory streamed to its end
        self.late_cycles = 0
        """Cycles that went out a whole period or more after their deadline."""
        self.lateness_max_ns = 0
        """Largest lateness of a cycle [ns]."""
        self.silent_drives: set[int] = set()
        """Legs (1..6) whose heartbeat was lost since the last ARM."""
        self.following_error_window_um = round(FOLLOWING_ERROR_LAG * self.table.geometry.leg_speed * 1e6)
        """The following error window 0x6065 written to every drive [µm] (:data:`FOLLOWING_ERROR_LAG`)."""
        self._sources: list[FaultSource] = []  # EMCYs since the last status (under _lock)

    # ----- connection -----------------------------------------------------------------------------------

    def connect(self) -> None:
        if self._network is not None:
            return
        network = canopen.Network(can.Bus(interface=self.interface, channel=self.channel, bitrate=self.bitrate))
        network.NOTIFIER_CYCLE = 0.05  # disconnect() waits up to one cycle
        self._network = network
        try:
            network.connect()
            self._drives = [_DriveLink(network.add_node(leg, drive_od.load_od(leg))) for leg in LEG_NODE_IDS]
            self._sensors = [_SensorLink(network.add_node(node_id, load_accelerometer_od(node_id)), k)
                             for k, node_id in enumerate(ACCELEROMETER_NODE_IDS[:self.accelerometer_count])]
            self._detector = _Link(network.add_node(DETECTOR_NODE_ID, load_detector_od())) if self.detector else None
            network.nmt.state = "PRE-OPERATIONAL"
            self._configure()
            started = time.monotonic_ns()
            network.nmt.state = "OPERATIONAL"
            for link in self._links():
                link.started_ns = started
            self._closing.clear()
            self._thread = threading.Thread(target=self._run, name="canopen-cycle", daemon=True)
            self._thread.start()
            self._wait_operational(time.monotonic() + self.connect_timeout)
            self._check_alive()
        except BaseException:
            self.close()
            raise

    def _links(self) -> list[_Link]:
        return [*self._drives, *self._sensors, *([self._detector] if self._detector else [])]

    def _wait_operational(self, deadline: float) -> None:
        """Until every node's heartbeat reports NMT operational and the first status is out (at most until
        ``deadline`` [s, monotonic]). A node whose heartbeat, sent after the last start command, reports another
        state (it missed the command, or booted again) is started once more."""
        def ready() -> bool:
            return self._failure is not None or (self.feedback.latest is not None and not self._behind())

        while not self.feedback.wait_for(ready, HEARTBEAT_PERIOD):
            if time.monotonic() > deadline:
                raise TableTimeoutError(f"{self.url}: not every node reported operational in its heartbeat within "
                                        f"{self.connect_timeout} s ({self._nmt_states()})")
            for link in self._behind():
                if link.heartbeat_ns is not None and link.heartbeat_ns > link.started_ns:
                    link.started_ns = time.monotonic_ns()
                    link.node.nmt.state = "OPERATIONAL"

    def _behind(self) -> list[_Link]:
        """The nodes whose last heartbeat did not report NMT operational."""
        return [link for link in self._links() if link.nmt_state != _NMT_OPERATIONAL]

    def nmt_states(self) -> dict[int, str]:
        """Each node's NMT state as its last heartbeat reported it (node id → name; "silent" before one)."""
        return {link.node.id: "silent" if link.nmt_state is None
                else canopen.nmt.NMT_STATES.get(link.nmt_state, hex(link.nmt_state)).lower()
                for link in self._links()}

    def _nmt_states(self) -> str:
        return ", ".join(f"node {node} {state}" for node, state in self.nmt_states().items())

    def _configure(self) -> None:
        """SDO configuration of every node (module docstring)."""
        heartbeat_ms = round(HEARTBEAT_PERIOD * 1000)
        consumer = heartbeat_consumer_entry(MASTER_NODE_ID, round(CONSUMER_TIME * 1000))
        geometry = self.table.geometry
        deadline = time.monotonic() + self.connect_timeout
        delays = set()
        for link in self._drives:
            node = link.node
            sdo = self._sdo(node, deadline)
            if sdo[drive_od.DEVICE_TYPE].raw != drive_od.DEVICE_TYPE_CIA402_SERVO or not (
                    sdo[drive_od.SUPPORTED_DRIVE_MODES].raw & drive_od.SUPPORTED_MODE_CSP):
                raise TableError(f"{self.url}: node {node.id} is not a CiA 402 servo drive with CSP")
            sdo[drive_od.PRODUCER_HEARTBEAT_TIME].raw = heartbeat_ms
            sdo[drive_od.CONSUMER_HEARTBEAT_TIME][1].raw = consumer
            sdo[drive_od.COMMUNICATION_CYCLE_PERIOD].raw = self.period_ns // 1000
            low, high = self.scaling.software_position_limits
            sdo[drive_od.SOFTWARE_POSITION_LIMIT][1].raw = low
            sdo[drive_od.SOFTWARE_POSITION_LIMIT][2].raw = high
            sdo[drive_od.MAX_PROFILE_VELOCITY].raw = velocity_increments(geometry.leg_speed)
            sdo[drive_od.FOLLOWING_ERROR_WINDOW].raw = self.following_error_window_um
            sdo[drive_od.MODES_OF_OPERATION].raw = drive_od.MODE_CYCLIC_SYNCHRONOUS_POSITION
            if sdo[drive_od.MODES_OF_OPERATION_DISPLAY].raw != drive_od.MODE_CYCLIC_SYNCHRONOUS_POSITION:
                raise TableError(f"{self.url}: drive {node.id} did not take cyclic synchronous position mode")
            for pdo_map, spec in ((node.rpdo[1], RPDO1), (node.tpdo[1], TPDO1)):
                configure(pdo_map, spec, node.id)
                pdo_map.save()
            delays.add((sdo[drive_od.TARGET_DELAY].raw, sdo[drive_od.FEEDBACK_DELAY].raw))
            node.tpdo[1].add_callback(lambda pdo_map, link=link: self._on_drive(link, pdo_map))
            node.emcy.add_callback(lambda error, link=link: self._on_emcy(link, error))
        if len(delays) != 1:
            raise TableError(f"{self.url}: the drives declare different target/feedback delays {sorted(delays)} µs")
        (target_us, feedback_us), = delays
        self.target_delay_ns, self.feedback_delay_ns = target_us * 1000, feedback_us * 1000
        sample_delays = set()
        for sensor in self._sensors:
            sdo = self._sdo(sensor.node, deadline)
            sdo[drive_od.PRODUCER_HEARTBEAT_TIME].raw = heartbeat_ms
            configure(sensor.node.tpdo[1], ACCEL_TPDO1, sensor.node.id)
            sensor.node.tpdo[1].save()
            sample_delays.add(sdo[SAMPLE_DELAY].raw)
            sensor.node.tpdo[1].add_callback(lambda pdo_map, sensor=sensor: self._on_accel(sensor, pdo_map))
        if len(sample_delays) > 1:
            raise TableError(f"{self.url}: the accelerometers declare different sample delays {sorted(sample_delays)}")
        self.sample_delay_ns = sample_delays.pop() * 1000 if sample_delays else 0
        if self._detector is not None:
            node = self._detector.node
            self._sdo(node, deadline)[drive_od.PRODUCER_HEARTBEAT_TIME].raw = heartbeat_ms
            configure(node.tpdo[1], EVENT_TPDO1, node.id)
            node.tpdo[1].save()
            node.tpdo[1].add_callback(self._on_event)

    def _sdo(self, node: canopen.RemoteNode, deadline: float) -> Any:
        """The node's SDO client once the node answers (asked until ``deadline`` [s, monotonic]: a node may still
        be booting), with :data:`SDO_TIMEOUT` per request."""
        node.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT
        while True:
            try:
                node.sdo[drive_od.DEVICE_TYPE].raw  # noqa: B018 - the read is the question
                return node.sdo
            except canopen.SdoCommunicationError:
                if time.monotonic() > deadline:
                    raise TableTimeoutError(f"{self.url}: node {node.id} does not answer SDO (is it on the bus?)") \
                        from None

    def close(self) -> None:
        if self._network is None:
            return
        self._closing.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        self._network.disconnect()
        self._network = None
        self.feedback.close()

    def _check_alive(self) -> None:
        if self._failure is not None:
            raise TableError(f"{self.url}: the CANopen cycle stopped: {self._failure!r}") from self._failure
        if self._network is None:
            raise TableError(f"{self.url}: not connected")

    # ----- receiving (the network's thread) ---------------------------------------------------------------

    def _answered(self, timestamp: float) -> tuple[int, int] | None:
        """(index, deadline [ns]) of the SYNC a frame with this time stamp answered: the last one sent before it."""
        with self._lock:
            for wall, index, deadline in reversed(self._syncs):
                if wall <= timestamp:
                    return index, deadline
        return None

    def _on_drive(self, link: _DriveLink, pdo_map: Any) -> None:
        feedback = TPDO1.decode(bytes(pdo_map.data))
        answered = self._answered(pdo_map.timestamp)
        with self._lock:
            link.statusword, link.position = feedback.statusword, feedback.position_actual
            if answered is not None:
                self._frames.setdefault(answered[0], {})[self._drives.index(link)] = feedback.position_actual

    def _on_accel(self, sensor: _SensorLink, pdo_map: Any) -> None:
        answered = self._answered(pdo_map.timestamp)
        if answered is None:
            return
        force = decode_force(ACCEL_TPDO1.decode(bytes(pdo_map.data)))
        index = answered[0]
        if sensor.next_index is not None and index != sensor.next_index:
            self._publish_accel(sensor)
            sensor.lost += max(0, index - sensor.next_index)
            sensor.seq += 1  # a gap in the batches' sequence numbers marks the lost samples
        sensor.pending.append((index, force))
        sensor.next_index = index + 1
        if len(sensor.pending) >= ACCEL_BATCH:
            self._publish_accel(sensor)

    def _deadline(self, index: int) -> int | None:
        """The deadline [ns] of SYNC ``index`` (None once forgotten: 512 cycles back)."""
        with self._lock:
            return next((d for _, i, d in reversed(self._syncs) if i == index), None)

    def _publish_accel(self, sensor: _SensorLink) -> None:
        if not sensor.pending:
            return
        deadline = self._deadline(sensor.pending[0][0])
        if deadline is not None:
            self.feedback.publish_accel(AccelBatch(sensor.sensor_id, sensor.seq, deadline - self.sample_delay_ns,
                                                   self.period_ns, np.array([f for _, f in sensor.pending])))
            sensor.seq += 1
        else:
            sensor.lost += len(sensor.pending)
        sensor.pending.clear()

    def _on_event(self, pdo_map: Any) -> None:
        record = EVENT_TPDO1.decode(bytes(pdo_map.data))
        received = time.monotonic_ns() - round((time.time() - pdo_map.timestamp) * 1e9)
        self.feedback.publish_detection(Detection(record.event_id, record.body_id, record.direction,
                                                  event_tilt(record), received - event_age_ns(record)))

    def _on_emcy(self, link: _DriveLink, error: Any) -> None:
        if error.code & 0xFF00 == 0:
            return  # error reset
        with self._lock:
            link.emcy.append((error.code, time.monotonic_ns()))
            self._sources.append(FaultSource(link.node.id, error.code))
            self._fault(_EMCY_FAULTS.get(error.code, "DRIVE"))

    # ----- the cycle ------------------------------------------------------------------------------------

    def _run(self) -> None:
        heartbeat_every = max(1, round(MASTER_HEARTBEAT_PERIOD * 1e9 / self.period_ns))
        status_every = max(1, round(1e9 / STATUS_RATE / self.period_ns))
        deadline = time.monotonic_ns() + self.period_ns
        index = 0
        try:
            while not self._closing.is_set():
                self._next_deadline = deadline
                lateness = sleep_until(deadline)
                statuses, sources = self._cycle(index, deadline, lateness, index % heartbeat_every == 0,
                                                status_every)
                for status in statuses:
                    self.feedback.publish_status(status, sources)
                index += 1
                deadline += self.period_ns
        except BaseException as exc:  # the drives' heartbeat consumers notice the silence and stop the table
            self._failure = exc
            self.feedback.notify()

    def _cycle(self, index: int, deadline: int, lateness: int, heartbeat: bool,
               status_every: int) -> tuple[list[TableStatus], tuple[FaultSource, ...]]:
        """One cycle at ``deadline`` (module docstring); the statuses to publish and the EMCYs received before them
        (the sources of the faults they raise)."""
        assert self._network is not None
        now = time.monotonic_ns()
        with self._lock:
            self._cycle_index = index
            self._count_lateness(lateness)
            self._supervise(now, deadline)
            setpoints = self._setpoints(deadline + self.target_delay_ns)
            self._status_owed |= self._state != self._published_state  # until a SYNC all six answered shows it
        send = self._network.send_message
        for link, setpoint in zip(self._drives, setpoints, strict=True):
            send(RPDO1.cob_id(link.node.id), RPDO1.encode(setpoint))
        with self._lock:
            self._syncs.append((time.time(), index, deadline))
        send(SYNC_COB_ID, b"")
        if heartbeat:
            send(_HEARTBEAT_COB_ID + MASTER_NODE_ID, bytes([_NMT_OPERATIONAL]))
        with self._lock:
            statuses = self._statuses(now, status_every)
            sources = tuple(self._sources) if statuses else ()
            if statuses:
                self._sources.clear()
            return statuses, sources

    def _count_lateness(self, lateness: int) -> None:
        self.lateness_max_ns = max(self.lateness_max_ns, lateness)
        self.late_cycles += lateness >= self.period_ns
        if self._state != "streaming":
            return
        self._stream_cycles += 1
        if self._lateness is not None:
            self._lateness.append(lateness)
        if lateness > self.target_delay_ns - self.period_ns:  # the drives played their last target already
            if not self._dry:
                self._underruns += 1
                self._faults.add("UNDERRUN")
            self._dry = True
        else:
            self._dry = False

    def _supervise(self, now: int, deadline: int) -> None:
        """Faults from heartbeats and statuswords; the state changes the drives' states and the clock decide."""
        for leg, link in enumerate(self._drives, start=1):
            age = link.heartbeat_age(now)
            if age is not None and age > NODE_CONSUMER_TIME:
                self.silent_drives.add(leg)
                self._fault("DRIVE")
            if self._state in _DRIVING and link.state in _FAULTY and not link.node.emcy.active:
                self._fault("DRIVE")  # in fault without an EMCY (lost, or sent before this master listened)
            if link.statusword is not None and link.statusword & StatusBit.INTERNAL_LIMIT_ACTIVE:
                self._faults.add("SETPOINT_LIMIT")
        states = [link.state for link in self._drives]
        enabled = [s is State.OPERATION_ENABLED for s in states]
        if self._arming and all(enabled):
            self._arming = False
            self._pose = self._measured_pose()
            self._velocity[:] = 0.0
            self._set_state("armed")
        elif self._state == "stopping" and self._stop_reason is not None and not any(
                e or s is State.FAULT_REACTION_ACTIVE for e, s in zip(enabled, states, strict=True)):
            self._set_state("faulted")
        elif self._state in ("homing", "tilting") and self._move is not None and self._arrived(self._move, deadline):
            self._move = None
            self._set_state("armed")
        elif self._state == "streaming" and self._trajectory is not None and deadline >= self._trajectory.t_end_ns:
            self._played, self._trajectory = self._trajectory, None
            self._set_state("armed")
        elif (self._state == "stopping" and self._stop_reason is None and self._homing_after_stop
              and self._move is not None and self._arrived(self._move, deadline)):
            self._move = None
            self._set_state("armed")

    def _arrived(self, move: Move, deadline: int) -> bool:
        """Whether ``move`` has ended: its reference arrived and the newest measured pose is in position (a DRIVE
        fault, which stops the table, when that is overdue)."""
        if deadline < move.end_ns:
            return False
        complete = [index for index, frame in self._frames.items() if len(frame) == len(self._drives)]
        if complete and move.in_position(self._frame_pose(self._frames[max(complete)])):
            deadline_in_position = self._deadline(max(complete))
            if deadline_in_position is not None:
                self._arrived_ns = deadline_in_position - self.feedback_delay_ns
            return True
        if move.settle_overdue(deadline):
            self._fault("DRIVE")  # a following error: the legs did not reach their targets
        return False

    def _fault(self, name: str) -> None:
        """Latch a fault; a stopping one quick-stops every drive (module docstring)."""
        self._faults.add(name)
        if name in _STOPPING_FAULTS and (self._state in _DRIVING or self._state == "stopping" or self._arming):
            self._arming = False
            self._stop_reason = self._stop_reason or name
            self._move = self._trajectory = None
            self._set_state("stopping")

    def _set_state(self, state: str) -> None:
        self._state = state
        if state != "stopping":
            self._homing_after_stop = False

    def _setpoints(self, tau: int) -> list[Setpoint]:
        """Each drive's controlword and target for the SYNC whose targets are reached at ``tau``."""
        reference = self._reference(tau)
        targets = [link.position for link in self._drives]
        if reference is not None:
            targets = self._targets(reference)
        setpoints = []
        for link, target in zip(self._drives, targets, strict=True):
            word = controlword(self._command(link))
            if word & link.word & 0x80:  # a fault reset acts on a rising bit 7: a word with it clear in between
                word = controlword(Command.DISABLE_VOLTAGE)
            link.word = word
            setpoints.append(Setpoint(word, target))
        return setpoints

    def _command(self, link: _DriveLink) -> Command:
        """What a drive is told in the current state."""
        if self._arming:
            return command_towards_operation(link.state or State.SWITCH_ON_DISABLED) or (
                Command.ENABLE_OPERATION if link.state is State.OPERATION_ENABLED else Command.DISABLE_VOLTAGE)
        if self._state in _DRIVING or (self._state == "stopping" and self._stop_reason is None):
            return Command.ENABLE_OPERATION
        if self._state in ("stopping", "faulted", "emergency_stopped"):
            return Command.QUICK_STOP
        return Command.DISABLE_OPERATION  # idle

    def _reference(self, tau: int) -> np.ndarray | None:
        """The reference pose at ``tau`` (None when the drives hold their own positions)."""
        if not (self._state in _DRIVING or (self._state == "stopping" and self._stop_reason is None)):
            return None
        dt = (tau - self._tau) * 1e-9 if self._tau else self.period_ns * 1e-9
        previous = self._pose
        if self._state in ("homing", "tilting") and self._move is not None:
            pose = self._move.at(tau)
        elif self._state == "streaming" and self._trajectory is not None:
            pose = self._trajectory.at(tau)
        elif self._state == "stopping" and self._move is not None:
            pose = self._move.at(tau)
        elif self._state == "stopping":  # decelerate at the axis limits, then move home
            slower = np.sign(self._velocity) * np.maximum(np.abs(self._velocity) - self._acceleration * dt, 0.0)
            pose = previous + slower * dt
            if not slower.any():
                self._move = Move.shortest(tau, pose, np.zeros(6), self.table)
                self._homing_after_stop = True
        else:
            pose = previous
        self._velocity = (pose - previous) / dt if dt > 0 else np.zeros(6)
        self._pose, self._tau = pose, tau
        return pose

    def _targets(self, pose: np.ndarray) -> list[int]:
        """Target positions [µm] of a pose: clipped to the envelope and the legs' stroke (latching the faults)."""
        clipped = np.clip(pose, -self._bounds, self._bounds)
        if not np.array_equal(clipped, pose):
            self._faults.add("SETPOINT_LIMIT")
        g = self.table.geometry
        wanted = self.table.leg_lengths(clipped)
        lengths = np.clip(wanted, g.leg_min, g.leg_max)
        if not np.array_equal(lengths, wanted):
            self._faults.add("STROKE")
        return list(self.scaling.positions(lengths.tolist()))

    def _frame_pose(self, frame: dict[int, int]) -> np.ndarray:
        """The pose (6,) of the leg positions [µm] one SYNC's TPDOs reported (forward kinematics)."""
        lengths = np.array(self.scaling.lengths([frame[leg] for leg in range(len(self._drives))]))
        return self.table.pose_from_leg_lengths(lengths, guess=self._measured)

    def _measured_pose(self) -> np.ndarray:
        lengths = np.array(self.scaling.lengths([link.position for link in self._drives]))
        self._measured = self.table.pose_from_leg_lengths(lengths, guess=self._measured)
        return self._measured.copy()

    def _statuses(self, now: int, every: int) -> list[TableStatus]:
        """A status for every ``every``-th SYNC all six drives answered since the last call, in order — 50 Hz of
        measured time, whenever the answers arrive — and for the newest one when the state changed since the last
        status."""
        complete = sorted(index for index, frame in self._frames.items() if len(frame) == len(self._drives))
        if not complete:
            return []
        due = [index for index in complete if index % every == 0]
        if self._status_owed and complete[-1] not in due:
            due.append(complete[-1])
        statuses = [self._status(index, deadline, now) for index in due
                    if (deadline := self._deadline(index)) is not None]
        for old in [i for i in self._frames if i <= complete[-1]]:
            del self._frames[old]
        self._status_owed = False
        return statuses

    def _status(self, index: int, deadline: int, now: int) -> TableStatus:
        """The status of SYNC ``index`` (at ``deadline``): the pose its TPDOs report, the state now."""
        self._measured = self._frame_pose(self._frames[index])
        depth = 0
        if self._state == "streaming" and self._trajectory is not None:
            depth = len(self._trajectory.poses) - self._trajectory.due(self._tau)
        self._published_state = self._state
        faults = tuple(name for name in FAULT_ORDER if name in self._faults)
        return TableStatus(deadline - self.feedback_delay_ns, self._state, depth, self._cycle_index % 2**32,
                           self._underruns, faults, 0, self._measured.copy(), now)

    # ----- commands ---------------------------------------------------------------------------------------

    def _refuse(self, name: str, why: str) -> None:
        raise CommandRejectedError(name, "TEMPORARILY_REJECTED", self._state, why)

    def _status_after(self, host_ns: int) -> None:
        """Wait (at most :data:`STATUS_WAIT`) for a status made after ``host_ns``: it shows what a command did."""
        self.feedback.wait_for(lambda: self.feedback.latest is not None and self.feedback.latest.host_ns > host_ns,
                               STATUS_WAIT)

    def _wait_state(self, name: str, done: Callable[[], bool], timeout: float) -> None:
        if not self.feedback.wait_for(lambda: done() or self._failure is not None, timeout):
            states = ", ".join(f"leg {leg} {link.state.value if link.state else 'silent'}"
                               for leg, link in enumerate(self._drives, start=1))
            raise TableTimeoutError(f"{name}: not done within {timeout} s ({states})")
        self._check_alive()

    def arm(self) -> None:
        self._check_alive()
        with self._lock:
            if self._state not in ("idle", "armed", "faulted", "emergency_stopped"):
                self._refuse("ARM", "not accepted in this state")
            now = time.monotonic_ns()
            ages = [link.heartbeat_age(now) for link in self._drives]
            silent = [leg for leg, age in enumerate(ages, start=1) if age is None or age > NODE_CONSUMER_TIME]
            if silent:
                raise CommandFailedError("ARM", "FAILED", self._state,
                                         f"no heartbeat from leg {', '.join(map(str, silent))}")
            stopped = [leg for leg, link in enumerate(self._drives, start=1) if link.nmt_state != _NMT_OPERATIONAL]
            if stopped:  # its PDOs do not work (a drive that rebooted has lost its configuration: connect again)
                legs = ", ".join(map(str, stopped))
                raise CommandFailedError("ARM", "FAILED", self._state,
                                         f"leg {legs} not NMT operational ({self._nmt_states()})")
            self._faults.clear()
            self.silent_drives.clear()
            self._stop_reason = None
            if self._state == "armed":
                return
            self._arming = True
        try:
            self._wait_state("ARM", lambda: self._state == "armed" and not self._arming, self.command_timeout)
        except TableError:
            with self._lock:
                self._arming = False
            raise
        self._status_after(time.monotonic_ns())

    def disarm(self) -> None:
        self._check_alive()
        with self._lock:
            if self._state not in ("idle", "armed", "faulted"):
                self._refuse("DISARM", "only at rest (armed or faulted)")
            self._set_state("idle")  # the drives are told to disable operation from the next cycle
        self._wait_state("DISARM", lambda: not any(link.state is State.OPERATION_ENABLED for link in self._drives),
                         self.command_timeout)
        self._status_after(time.monotonic_ns())

    def _motion(self, name: str, target: Callable[[np.ndarray], np.ndarray], state: str, wait: bool,
                timeout: float) -> None:
        """Start a move from the reference to ``target(reference)``; with ``wait``, until it is over."""
        self._check_alive()
        with self._lock:
            if self._state != "armed":
                self._refuse(name, "not accepted in this state")
            move = Move.shortest(self._tau, self._pose, target(self._pose.copy()), self.table)
            if move.duration_ns == 0:
                return
            self._move = move
            self._set_state(state)
        if not wait:
            return
        self._wait_state(name, lambda: self._state != state, timeout)
        if self._state != "armed":
            raise CommandFailedError(name, "FAILED", self._state, "the motion was stopped before its target")
        shown = self._arrived_ns  # the status of the SYNC found in position (published in the same cycle)
        self.wait_for_status(lambda s: s.t_ns >= shown, STATUS_TIMEOUT)

    def home(self, *, wait: bool = True, timeout: float = 120.0) -> None:
        self._motion("HOME", lambda pose: np.zeros(6), "homing", wait, timeout)

    def set_tilt(self, angle: float, axis: str = "pitch", *, wait: bool = True, timeout: float = 120.0) -> None:
        if axis not in TILT_AXES:
            raise ValueError(f"axis must be one of {TILT_AXES}, got {axis!r}")
        if not math.isfinite(angle):
            raise ValueError(f"angle must be finite, got {angle!r}")
        if abs(angle) > self.table.limits.tilt.angle:
            raise CommandFailedError("SET_TILT", "FAILED", self._state,
                                     f"invalid parameters: |{angle}| rad beyond the tilt limit "
                                     f"{self.table.limits.tilt.angle} rad")
        column = 4 if axis == "pitch" else 3

        def tilted(pose: np.ndarray) -> np.ndarray:
            pose[column] = angle
            return pose

        self._motion("SET_TILT", tilted, "tilting", wait, timeout)

    def stop(self) -> None:
        self._check_alive()
        with self._lock:
            if self._state in _MOVING:
                self._move = self._trajectory = None
                self._stop_reason = None
                self._set_state("stopping")
        self._status_after(time.monotonic_ns())

    def emergency_stop(self) -> None:
        self._check_alive()
        with self._lock:
            self._arming = False
            self._move = self._trajectory = None
            self._set_state("emergency_stopped")
        self._status_after(time.monotonic_ns())

    # ----- streaming ------------------------------------------------------------------------------------

    def stream(self, t: np.ndarray, poses: np.ndarray, *, lead: float = 0.075,
               on_progress: Callable[[int, int], None] | None = None,
               on_start: Callable[[int], None] | None = None) -> StreamReport:
        self._check_alive()
        poses = finite_poses(poses)
        spacing_ns = round(sample_spacing(t, len(poses)) * 1e9)
        shortest = (self.target_delay_ns + self.period_ns) * 1e-9
        if not (math.isfinite(lead) and lead > shortest):
            raise ValueError(f"lead must exceed {shortest:g} s (the drives' target delay and a cycle), got {lead!r}")
        with self._lock:
            if self._state != "armed":
                self._refuse("START_STREAM", "not accepted in this state")
            now = time.monotonic_ns()
            anchor = max(self._tau, self._next_deadline + self.target_delay_ns)
            trajectory = Trajectory(anchor, self._pose.copy(), now + round(lead * 1e9), spacing_ns, poses)
            self._trajectory = trajectory
            underruns_before = self._underruns
            self._lateness, self._stream_cycles, self._dry = [], 0, False
            self._set_state("streaming")
        if on_start is not None:
            on_start(trajectory.t_start_ns)
        next_progress = time.monotonic_ns() + 100_000_000
        while not self.feedback.wait_for(lambda: self._state != "streaming" or self._failure is not None,
                                         max(0.0, (next_progress - time.monotonic_ns()) * 1e-9)):
            if on_progress is not None:
                on_progress(trajectory.due(self._tau), len(poses))
            next_progress += 100_000_000
        self._check_alive()
        final = self.wait_for_status(lambda s: s.state != "streaming", 1.0)
        if on_progress is not None:
            on_progress(trajectory.due(self._tau) if final.state in STOPPED_STATES else len(poses), len(poses))
        with self._lock:
            lateness = np.array(self._lateness or [], dtype=np.int64)
            self._lateness = None
            report = StreamReport(self._stream_cycles, len(poses), self._underruns - underruns_before,
                                  trajectory.t_start_ns, trajectory.t_end_ns, lead, lateness, final)
            played = self._played is trajectory
        if final.state != "armed" or not played:  # stopped (and home again) before its end
            raise StreamAbortedError(f"the table stopped the stream ({final.state}, faults "
                                     f"{', '.join(final.faults) or 'none'})", report)
        return report

    # ----- diagnostics ------------------------------------------------------------------------------------

    def link_stats(self) -> dict[str, Any]:
        """Bus load, rate, cycle lateness, accelerometer samples lost, duplicate overturn events dropped, each
        node's heartbeat age [s] and NMT state, and the EMCY codes received per node."""
        now = time.monotonic_ns()
        links = self._links()
        return {"rate_hz": self.rate, "bitrate": self.bitrate, "bus_load": self.bus_load,
                "target_delay_s": self.target_delay_ns * 1e-9, "feedback_delay_s": self.feedback_delay_ns * 1e-9,
                "late_cycles": self.late_cycles, "lateness_max_s": self.lateness_max_ns * 1e-9,
                "accel_samples_lost": sum(s.lost for s in self._sensors),
                "duplicate_detections": self.feedback.duplicate_detections,
                "heartbeat_age_s": {link.node.id: link.heartbeat_age(now) for link in links},
                "nmt_state": self.nmt_states(),
                "emcy": {link.node.id: [code for code, _ in link.emcy] for link in links if link.emcy},
                "silent_drives": sorted(self.silent_drives)}


register_scheme("canopen", CanopenTable)
