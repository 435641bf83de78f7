"""The table controller over CANopen: ``open_table("canopen://CHANNEL?interface=NAME")``.

This host is the **CANopen master** of the table: six CiA 402 leg drives in cyclic synchronous position mode (CSP),
the plate accelerometers and the overturn detector (node ids, EDS and PDO maps in :mod:`protocols.canopen`). On
CANopen the table controller of ``docs/table-controller.md`` is this master: it plays every motion itself and
sends the drives a leg length [µm] per cycle.

URL ``canopen://CHANNEL?interface=NAME[&bitrate=N][&rate=HZ][&accelerometers=N]``: python-can's channel and
interface, the bus bitrate [bit/s] (default 1 Mbit/s), the SYNC (setpoint) rate [Hz] (default 500; a rate whose
worst-case cycle exceeds 80 % of the bitrate is refused: :class:`~protocols.canopen.BusLoadError`) and the number
of accelerometer nodes (default 1); the same names as keyword options of :func:`~drivers.controller.open_table`
(a keyword wins). Controller time is this master's clock (host monotonic ns, or the ``clock`` option's). Nothing
is signed: CAN has no authentication, the bus is the table's private cable.

Modules, one job each: :mod:`~drivers.canopen.setup` NMT, SDO and PDO set-up; :mod:`~drivers.canopen.cycle` the
SYNC cycle thread; :mod:`~drivers.canopen.feedback` the frames received and the statuses;
:mod:`~drivers.canopen.faults` fault supervision; :mod:`~drivers.canopen.motion` the commands and the reference;
:mod:`~drivers.canopen.nodes` what the master knows of each node; :mod:`~drivers.canopen.master` the options and
state they share; :class:`~drivers.canopen.table.CanopenTable` all of them.

Connecting, the cycle, each command and fault on CiA 402, time stamps and the SYNC counter: docs/canopen.md §The
master.
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
