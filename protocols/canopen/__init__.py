"""CANopen CiA 402 wire formats of the hexapod's leg drives.

- :mod:`~protocols.canopen.od` — the drive's EDS (``leg_drive.eds``), object indices and values, node ids
- :mod:`~protocols.canopen.pdo_maps` — RPDO1 (controlword + target position) and TPDO1 (statusword + position
  actual), both synchronous, as data that configures ``canopen`` PDO maps, with payload encode/decode
- :mod:`~protocols.canopen.scaling` — leg length [m] ↔ position increments (1 µm, 0 at the leg's minimum length)
- :mod:`~protocols.canopen.cia402` — the drive state machine's controlword commands and statusword states
- :mod:`~protocols.canopen.bus_load` — worst-case bus load of the SYNC cycle; the 500 Hz default rate
- :mod:`~protocols.canopen.sensors` — the plate accelerometers (a TPDO on every SYNC) and the overturn detector
  (an event TPDO per overturn): EDS, node ids, PDO maps, scaling
"""

from protocols.canopen.bus_load import (
    DEFAULT_LIMIT,
    DEFAULT_RATE_HZ,
    BusLoadError,
    bus_load,
    check_bus_load,
    cycle_bits,
    cycle_period_us,
    frame_bits,
    max_rate_hz,
)
from protocols.canopen.cia402 import (
    Command,
    State,
    StatusBit,
    command_towards_operation,
    controlword,
    decode_controlword,
    decode_statusword,
    statusword,
    transition,
)
from protocols.canopen.od import (
    EDS_PATH,
    LEG_NODE_IDS,
    MASTER_NODE_ID,
    decode_heartbeat_consumer_entry,
    heartbeat_consumer_entry,
    load_od,
)
from protocols.canopen.pdo_maps import (
    PDO_MAPS,
    RPDO1,
    TPDO1,
    TPDO1_COUNTED,
    CountedFeedback,
    Feedback,
    MappedObject,
    PdoError,
    PdoSpec,
    Setpoint,
    configure,
)
from protocols.canopen.scaling import INCREMENTS_PER_METRE, LegRangeError, LegScaling, velocity, velocity_increments

__all__ = [
    "DEFAULT_LIMIT",
    "DEFAULT_RATE_HZ",
    "EDS_PATH",
    "INCREMENTS_PER_METRE",
    "LEG_NODE_IDS",
    "MASTER_NODE_ID",
    "PDO_MAPS",
    "RPDO1",
    "TPDO1",
    "TPDO1_COUNTED",
    "BusLoadError",
    "Command",
    "CountedFeedback",
    "Feedback",
    "LegRangeError",
    "LegScaling",
    "MappedObject",
    "PdoError",
    "PdoSpec",
    "Setpoint",
    "State",
    "StatusBit",
    "bus_load",
    "check_bus_load",
    "command_towards_operation",
    "configure",
    "controlword",
    "cycle_bits",
    "cycle_period_us",
    "decode_controlword",
    "decode_heartbeat_consumer_entry",
    "decode_statusword",
    "frame_bits",
    "heartbeat_consumer_entry",
    "load_od",
    "max_rate_hz",
    "statusword",
    "transition",
    "velocity",
    "velocity_increments",
]
