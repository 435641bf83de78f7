"""The CANopen master's options and shared state (:class:`MasterBase`), on which each module of the package does
one job: :mod:`~drivers.canopen.setup` (NMT, SDO, PDO mapping; connect and close), :mod:`~drivers.canopen.cycle`
(the SYNC cycle thread), :mod:`~drivers.canopen.feedback` (the frames received and the statuses made of them),
:mod:`~drivers.canopen.faults` (fault supervision) and :mod:`~drivers.canopen.motion` (the commands and the
reference the master plays); :class:`~drivers.canopen.table.CanopenTable` combines them."""

from __future__ import annotations

import math
import threading
from abc import abstractmethod
from collections import deque
from urllib.parse import parse_qs, urlsplit

import canopen
import numpy as np

from analysis.table.model import TableModel
from analysis.table.moves import Move, axis_limits
from drivers.canopen.clock import Clock, WallClock
from drivers.canopen.nodes import DriveLink, NodeLink, SensorLink
from drivers.canopen.survey import DriveReport
from drivers.canopen.trajectory import Trajectory
from drivers.controller import FaultSource, TableController, TableError, TableStatus
from protocols.canopen import (
    DEFAULT_LIMIT,
    DEFAULT_RATE_HZ,
    LEG_NODE_IDS,
    TPDO1,
    TPDO1_COUNTED,
    BusLoadError,
    PdoSpec,
    bus_load,
    check_bus_load,
    cycle_period_us,
)
from protocols.canopen.od import SYNC_COUNTER_MAX
from protocols.canopen.sensors import ACCEL_TPDO1, ACCEL_TPDO1_COUNTED, ACCELEROMETER_NODE_IDS, DETECTOR_NODE_ID

DEFAULT_BITRATE = 1_000_000
"""Bus bitrate [bit/s] unless the URL or an option says otherwise."""

FOLLOWING_ERROR_LAG = 0.010
"""How far behind its command a leg may be, as time at the legs' top speed [s]: each drive's following error window
0x6065 is this × the table model's leg speed (9000 µm at 0.9 m/s). A leg that follows trails its command by τ·v (a
first-order lag, τ = 5 ms for the table's drives), by at most 4.5 mm at top speed: the window is twice that bound.
A leg that stops while moving at v trips it (9 mm − τ·v)/v later: 5 ms at top speed, 85 ms at 0.1 m/s."""

NODE_CONSUMER_TIME = 0.2
"""The master's default consumer time of each node's heartbeat [s] (four periods), on the bus's clock: a node is
lost once frames that reached the bus this long after its last heartbeat have been handled and none of its
heartbeats among them (:meth:`~drivers.canopen.faults.FaultSupervision.silent`)."""

DRIVING_STATES = frozenset({"armed", "homing", "tilting", "streaming"})
"""States in which the drives follow the master's reference."""

_QUERY = ("interface", "bitrate", "rate", "accelerometers", "sync_counter")


def _flag(value: str | None, url: str) -> bool | None:
    if value is None:
        return None
    if value not in ("0", "1", "true", "false"):
        raise ValueError(f"table URL {url!r}: sync_counter must be 0 or 1, got {value!r}")
    return value in ("1", "true")


def _query(url: str) -> tuple[str, dict[str, str]]:
    parts = urlsplit(url)
    query = {key: values[-1] for key, values in parse_qs(parts.query).items()}
    unknown = sorted(set(query) - set(_QUERY))
    if parts.scheme != "canopen" or not parts.netloc or unknown:
        raise ValueError(f"table URL {url!r}: expected canopen://CHANNEL?interface=NAME[&bitrate=N][&rate=HZ]"
                         f"[&accelerometers=N][&sync_counter=0|1]" + (f" (unknown {', '.join(unknown)})" if unknown
                                                                      else ""))
    return parts.netloc, query


class MasterBase(TableController):
    """The options (those of :class:`~drivers.canopen.table.CanopenTable`), the nodes, and the controller
    state every part of the master reads and changes under ``_lock`` (re-entrant: the cycle thread, the network's
    thread and the caller's commands take it)."""

    def __init__(self, url: str, *, interface: str | None = None, bitrate: int | None = None,
                 rate: float | None = None, accelerometers: int | None = None, detector: bool = True,
                 table: TableModel | None = None, connect_timeout: float = 5.0, command_timeout: float = 2.0,
                 consumer_time: float = NODE_CONSUMER_TIME, sync_counter: bool | None = None,
                 clock: Clock | None = None) -> None:
        super().__init__(url)
        self.clock: Clock = clock or WallClock()
        """What paces the SYNC cycle and dates what the master stamps [ns] (:mod:`drivers.canopen.clock`: the host's
        monotonic clock unless given)."""
        if not (math.isfinite(consumer_time) and consumer_time > 0):
            raise ValueError(f"consumer_time must be > 0 s, got {consumer_time!r}")
        self.consumer_time = consumer_time
        """The consumer time of each node's heartbeat [s] (:data:`NODE_CONSUMER_TIME` unless given)."""
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
        self.table = table or TableModel()
        self.feedback.mount(self.table.sensors)
        self.drive_settings = self.table.drives
        """The rig configuration's ``[drives]`` (units, node ids, EDS files, options: :mod:`analysis.table.drives`)."""
        counted = _flag(query.get("sync_counter"), url) if sync_counter is None else sync_counter
        counted = self.drive_settings.sync_counter if counted is None else counted
        self.bus_load = check_bus_load(self.rate, len(LEG_NODE_IDS), self.bitrate, accelerometers=count)
        """Worst-case share of the bitrate the cycle takes."""
        if counted:
            self.bus_load = bus_load(self.rate, len(LEG_NODE_IDS), self.bitrate, count, counted=True)
            if self.bus_load > DEFAULT_LIMIT:
                raise BusLoadError(f"counted SYNCs at {self.rate:g} Hz take {self.bus_load:.1%} of {self.bitrate} "
                                   f"bit/s, beyond {DEFAULT_LIMIT:.0%}: lower the rate or leave sync_counter off")
        self.sync_counter = SYNC_COUNTER_MAX if counted else 0
        """The SYNC counter's overflow value (0x1019) the master sets, 0 when off. Opt-in (``sync_counter=1`` in the
        URL, the keyword, or ``[drives] sync_counter = true``), and refused at connect unless every drive's profile
        echoes the answered SYNC's counter (:mod:`drivers.canopen.profiles`): each SYNC then carries the counter and
        every TPDO the answered SYNC's (:mod:`protocols.canopen.pdo_maps`), so an answer is dated by its SYNC however
        late it comes (up to 240 cycles); off, by the last SYNC sent before its receive time, exact for drives that
        answer within the cycle."""
        self.drive_tpdo: PdoSpec = TPDO1_COUNTED if counted else TPDO1
        """The map of the drives' TPDO1."""
        self.accel_tpdo: PdoSpec = ACCEL_TPDO1_COUNTED if counted else ACCEL_TPDO1
        """The map of the accelerometers' TPDO1."""
        self.period_ns = cycle_period_us(self.rate) * 1000
        self.node_ids = tuple(leg.node_id for leg in self.drive_settings.legs)
        """The leg drives' node ids, leg 1..6 (``[drives.leg.N] node_id``; default the leg's number)."""
        clash = set(self.node_ids) & {*ACCELEROMETER_NODE_IDS[:count], *([DETECTOR_NODE_ID] if detector else [])}
        if clash:
            raise ValueError(f"drive node id {min(clash)} is a sensor's (accelerometers from "
                             f"0x{ACCELEROMETER_NODE_IDS[0]:02X}, detector 0x{DETECTOR_NODE_ID:02X}): give the drive "
                             "another one")
        lim = self.table.limits
        self._bounds = np.array([lim.surge.displacement, lim.lateral.displacement, lim.heave.displacement,
                                 lim.tilt.angle, lim.tilt.angle, math.inf])
        self._acceleration = axis_limits(self.table)[1]
        self.accelerometer_count = count
        self.detector = detector
        self.connect_timeout = connect_timeout
        self.command_timeout = command_timeout
        self.target_delay_ns = 0
        """The drives' target delay [ns]: a target latched at a SYNC is reached this long after it (their profile's,
        else ``[drives] target_delay_s``, else one cycle: a CSP drive reaches its target at the next SYNC)."""
        self.feedback_delay_ns = 0
        """The drives' feedback delay [ns]: a TPDO's position was measured this long before its SYNC (their
        profile's, else ``[drives] feedback_delay_s``, else 0)."""
        self.reports: list[DriveReport] = []
        """What each leg drive is (:mod:`drivers.canopen.survey`), read at connect."""
        self.sample_delay_ns = 0
        """The accelerometers' sample delay (0x2101) [ns]."""
        self.receive_buffer_bytes = 0
        """The bus socket's receive buffer [bytes] (:mod:`protocols.canopen.receive_buffer`; 0: not a socket)."""
        self._network: canopen.Network | None = None
        self._drives: list[DriveLink] = []
        self._sensors: list[SensorLink] = []
        self._detector: NodeLink | None = None
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
        self._demands: dict[int, list[int]] = {}  # SYNC index -> the targets [drive units] due then, legs in order
        self._driven = False  # the last targets followed a reference (not the drives' own positions, held)
        self._framed = -1  # the newest SYNC whose frame made the statuses: older answers came too late
        self._measured = np.zeros(6)
        self._played: Trajectory | None = None  # the last trajectory streamed to its end
        self.late_cycles = 0
        """Cycles that went out a whole period or more after their deadline."""
        self.lateness_max_ns = 0
        """Largest lateness of a cycle [ns]."""
        self.silent_drives: set[int] = set()
        """Legs (1..6) whose heartbeat was lost since the last ARM."""
        self.following_error_window: float | None = FOLLOWING_ERROR_LAG * self.table.geometry.leg_speed
        """The following error window 0x6065 written to every drive that has it [m of leg, converted to its units;
        None: off] (:data:`FOLLOWING_ERROR_LAG`)."""
        self._sources: list[FaultSource] = []  # EMCYs since the last status (under _lock)
        self._heard_stamp = 0.0  # the time stamp of the newest PDO handled [s, the bus's clock]
        self._heard_ns = 0  # when it was handled [ns, the master's clock]

    def _heard(self, stamp: float) -> None:
        """A PDO stamped ``stamp`` [s, the bus's clock] was handled now (the heartbeat consumers' evidence)."""
        self._heard_stamp = max(self._heard_stamp, stamp)
        self._heard_ns = self.clock.now_ns()

    def _links(self) -> list[NodeLink]:
        return [*self._drives, *self._sensors, *([self._detector] if self._detector else [])]

    def _check_alive(self) -> None:
        if self._failure is not None:
            raise TableError(f"{self.url}: the CANopen cycle stopped: {self._failure!r}") from self._failure
        if self._network is None:
            raise TableError(f"{self.url}: not connected")

    def _set_state(self, state: str) -> None:
        self._state = state
        if state != "stopping":
            self._homing_after_stop = False

    def _sync_counter(self, index: int) -> int:
        """The counter SYNC ``index`` carries (0: none)."""
        return index % self.sync_counter + 1 if self.sync_counter else 0

    def _deadline(self, index: int) -> int | None:
        """The deadline [ns] of SYNC ``index`` (None once forgotten: 512 cycles back)."""
        with self._lock:
            return next((d for _, i, d in reversed(self._syncs) if i == index), None)

    # --- what one part calls on another (CanopenTable combines them)

    @abstractmethod
    def _run(self) -> None:
        """The cycle thread (:mod:`~drivers.canopen.cycle`)."""

    @abstractmethod
    def _supervise(self, now: int, deadline: int) -> None:
        """Faults and state changes at the cycle of ``deadline`` [ns] (:mod:`~drivers.canopen.faults`)."""

    @abstractmethod
    def silent(self, link: NodeLink, now: int) -> bool:
        """Whether ``link``'s node has fallen silent at ``now`` [ns] (:mod:`~drivers.canopen.faults`)."""

    @abstractmethod
    def _on_emcy(self, link: DriveLink, error: canopen.emcy.EmcyError) -> None:
        """An EMCY from ``link``'s drive (:mod:`~drivers.canopen.faults`)."""

    @abstractmethod
    def _on_drive(self, link: DriveLink, data: bytes, stamp: float) -> None:
        """A drive's TPDO1 stamped ``stamp`` [s, the bus's clock] (:mod:`~drivers.canopen.feedback`)."""

    @abstractmethod
    def _on_accel(self, sensor: SensorLink, data: bytes, stamp: float) -> None:
        """An accelerometer's TPDO1 (:mod:`~drivers.canopen.feedback`)."""

    @abstractmethod
    def _on_event(self, data: bytes, stamp: float) -> None:
        """The overturn detector's event TPDO (:mod:`~drivers.canopen.feedback`)."""

    @abstractmethod
    def _frame_pose(self, frame: dict[int, int]) -> np.ndarray:
        """The pose of one SYNC's frame (:mod:`~drivers.canopen.feedback`)."""

    @abstractmethod
    def _measured_pose(self) -> np.ndarray:
        """The newest measured pose (:mod:`~drivers.canopen.feedback`)."""

    @abstractmethod
    def _statuses(self, now: int, every: int) -> list[TableStatus]:
        """The statuses owed at this cycle (:mod:`~drivers.canopen.feedback`)."""

    @abstractmethod
    def _reference(self, tau: int) -> np.ndarray | None:
        """The pose to reach at ``tau`` [ns] (None: hold) (:mod:`~drivers.canopen.motion`)."""

    @abstractmethod
    def _nmt_states(self) -> str:
        """Each node's NMT state, for a message (:mod:`~drivers.canopen.setup`)."""
