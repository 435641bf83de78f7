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
                  drive's heartbeat older than its consumer time (DRIVE: :data:`NODE_CONSUMER_TIME` on the
                  bus's clock, so a master that fell behind reading the bus judges the heartbeats waiting in it by
                  their time stamps; nothing at all heard from the bus for ``link_timeout``: all six) or
                  statusword bit 11 (internal limit: SETPOINT_LIMIT) latch a fault. DRIVE, HEARTBEAT_LOST and
                  STREAM_SILENT stop the table: a hexapod cannot make a coordinated move without one of its legs,
                  so the master quick-stops every drive (the doc's "decelerate, then home" is beyond a CSP master
                  then); ``stopping`` while a drive's fault reaction runs (the table's own, e.g. the emulator's
                  return home), then ``faulted``.
================  ================================================================================================

**Time.** On CANopen the controller is this master: controller time is its clock (host monotonic ns; the ``clock``
option, :mod:`~drivers.canopen.clock`, gives drives emulated in the same process a stepped one). Where the bus
has room for it (:attr:`~drivers.canopen.master.MasterBase.sync_counter`: the counted cycle within the 80 % limit,
e.g. 400 Hz or less with one accelerometer at 1 Mbit/s, not the default 500 Hz) the master turns the SYNC counter on
(0x1019 = 240 on every drive and accelerometer: each SYNC carries 1..240) and maps the answered SYNC's counter into
their TPDOs (``TPDO1_COUNTED``, ``ACCEL_TPDO1_COUNTED``): a frame answers the last SYNC sent before its time stamp
that carried its counter, so an answer that comes late — a drive, or an emulator process, held up for up to 240
cycles — is still dated by its own SYNC. Without the counter a frame answers the last SYNC sent before its time
stamp (python-can's: the receive time, or on the ``virtual`` bus the sender's): exact for drives that answer within
the cycle, as real CSP drives do. An answer for a SYNC whose status is out already is kept from the statuses, an
accelerometer sample for an index had (or counted lost) already is dropped (``accel_samples_stale``). A status
reports the pose of the newest SYNC all six drives answered, measured at that SYNC's time minus the feedback delay;
an accelerometer sample is from its SYNC's time minus the sample delay, so a sensor's count is duration × SYNC rate;
an overturn happened its age before its frame.

**Authentication.** CAN has none and neither does CANopen: this transport relies on the bus being a private cable
between the lab host and the table (nothing else attached, not bridged to a network). Nothing is signed, and the
controller (the emulator too) refuses no command for a signature: ``refused_commands`` stays 0.

**Modules.** :mod:`~drivers.canopen.setup` NMT, SDO and PDO set-up; :mod:`~drivers.canopen.cycle` the SYNC cycle
thread; :mod:`~drivers.canopen.feedback` the frames received and the statuses; :mod:`~drivers.canopen.faults` fault
supervision; :mod:`~drivers.canopen.motion` the commands and the reference; :mod:`~drivers.canopen.nodes` what the
master knows of each node; :mod:`~drivers.canopen.master` the options and state they share;
:class:`~drivers.canopen.table.CanopenTable` all of them.
"""

from analysis.table.moves import Move
from drivers.canopen.cycle import MASTER_HEARTBEAT_PERIOD, SYNC_COB_ID
from drivers.canopen.faults import FAULT_ORDER
from drivers.canopen.feedback import ACCEL_BATCH, STATUS_RATE
from drivers.canopen.master import DEFAULT_BITRATE, FOLLOWING_ERROR_LAG, NODE_CONSUMER_TIME
from drivers.canopen.motion import STATUS_WAIT
from drivers.canopen.setup import CONSUMER_TIME, HEARTBEAT_PERIOD, SDO_TIMEOUT
from drivers.canopen.table import CanopenTable
from drivers.canopen.trajectory import Trajectory
from drivers.controller import register_scheme

__all__ = [
    "ACCEL_BATCH",
    "CONSUMER_TIME",
    "DEFAULT_BITRATE",
    "FAULT_ORDER",
    "FOLLOWING_ERROR_LAG",
    "HEARTBEAT_PERIOD",
    "MASTER_HEARTBEAT_PERIOD",
    "NODE_CONSUMER_TIME",
    "SDO_TIMEOUT",
    "STATUS_RATE",
    "STATUS_WAIT",
    "SYNC_COB_ID",
    "CanopenTable",
    "Move",
    "Trajectory",
]

register_scheme("canopen", CanopenTable)
