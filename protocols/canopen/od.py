"""The leg drive's object dictionary: the packaged EDS, object indices and the values that go in them.

Each of the hexapod's six leg actuators is a CiA 402 drive described by ``leg_drive.eds`` (next to this
module). Leg k (1..6, the numbering of ``analysis.table.model``) is CANopen node ``k``; the master (the rig's
driver) produces its own heartbeat as node :data:`MASTER_NODE_ID`.

Units of the objects (CiA 402 "user units", declared in 0x60A8/0x60A9): position 1 increment = 1 µm of
joint-to-joint leg length with 0 at the leg's minimum length, velocity 1 increment/s = 1 µm/s (conversions in
:mod:`protocols.canopen.scaling`); 0x1006 in µs; 0x1016/0x1017 in ms.
"""

from __future__ import annotations

from pathlib import Path

import canopen

EDS_PATH = Path(__file__).with_name("leg_drive.eds")
"""The leg drive's electronic data sheet (CiA 306 EDS)."""

LEG_NODE_IDS = (1, 2, 3, 4, 5, 6)
"""Node id of leg 1..6: the leg number."""

MASTER_NODE_ID = 0x7F
"""Node id whose heartbeat (COB-ID 0x77F) the drives consume: the master's."""

# ----- object indices (CiA 301 communication profile, CiA 402 drive profile) ---------------------------

DEVICE_TYPE = 0x1000
ERROR_REGISTER = 0x1001
COB_ID_SYNC = 0x1005
COMMUNICATION_CYCLE_PERIOD = 0x1006
"""SYNC period [µs]."""
GUARD_TIME = 0x100C
"""UNSIGNED16 [ms]: the period at which the master guards the node (node guarding, CiA 301)."""
LIFE_TIME_FACTOR = 0x100D
"""UNSIGNED8: the node's life time is guard time × this: no guarding request for that long → life guarding event."""
COB_ID_EMCY = 0x1014
CONSUMER_HEARTBEAT_TIME = 0x1016
"""ARRAY; sub 1 holds one :func:`heartbeat_consumer_entry`."""
PRODUCER_HEARTBEAT_TIME = 0x1017
"""Heartbeat period [ms]; 0 = off."""
IDENTITY = 0x1018
"""RECORD: sub 1 vendor-ID, sub 2 product code, sub 3 revision number, sub 4 serial number (UNSIGNED32 each)."""
CONTROLWORD = 0x6040
STATUSWORD = 0x6041
MODES_OF_OPERATION = 0x6060
MODES_OF_OPERATION_DISPLAY = 0x6061
POSITION_ACTUAL_VALUE = 0x6064
FOLLOWING_ERROR_WINDOW = 0x6065
"""[increments]; the drive sets statusword bit 13 and faults (EMCY :data:`EMCY_FOLLOWING_ERROR`) when |following
error| exceeds it; 0xFFFFFFFF switches the supervision off."""
TARGET_POSITION = 0x607A
SOFTWARE_POSITION_LIMIT = 0x607D
"""ARRAY; sub 1 min, sub 2 max position limit [increments]."""
MAX_PROFILE_VELOCITY = 0x607F
"""[increments/s]."""
POLARITY = 0x607E
"""UNSIGNED8: bit 7 position polarity (the drive negates positions itself), bit 6 velocity polarity."""
POSITION_ENCODER_RESOLUTION = 0x608F
"""ARRAY: sub 1 encoder increments, sub 2 motor revolutions (UNSIGNED32)."""
GEAR_RATIO = 0x6091
"""ARRAY: sub 1 motor shaft revolutions, sub 2 driving shaft revolutions (UNSIGNED32)."""
FEED_CONSTANT = 0x6092
"""ARRAY: sub 1 feed [position units], sub 2 driving shaft revolutions (UNSIGNED32)."""
SI_UNIT_POSITION = 0x60A8
"""UNSIGNED32: the position unit (:mod:`protocols.canopen.units`)."""
SI_UNIT_VELOCITY = 0x60A9
INTERPOLATION_TIME_PERIOD = 0x60C2
"""RECORD: sub 1 mantissa (UNSIGNED8), sub 2 index (INTEGER8): the period the drive interpolates its targets over,
mantissa × 10^index s (:func:`protocols.canopen.units.interpolation_period`)."""
FOLLOWING_ERROR_ACTUAL_VALUE = 0x60F4
"""[increments]: position demand − position actual value (readable by SDO, not in TPDO1)."""
SUPPORTED_DRIVE_MODES = 0x6502
TARGET_DELAY = 0x2010
"""Manufacturer-specific (the project's leg drive, :data:`LEG_DRIVE_PRODUCT_CODE`: other vendors' 0x2010 means
something else), [µs]: a target position latched at a SYNC is reached this long after that SYNC (a CSP
drive: one cycle, the next SYNC). The master computes each target for its SYNC's time plus this."""
FEEDBACK_DELAY = 0x2011
"""Manufacturer-specific (the project's leg drive), [µs]: the position actual value in TPDO1 was measured this long
before its SYNC."""
ANSWERED_SYNC = 0x2012
"""Manufacturer-specific (the project's leg drive) UNSIGNED8, PDO-mappable: the counter of the SYNC the drive's
TPDO1 answers (0 when the SYNC carries none). Mapped by :data:`~protocols.canopen.pdo_maps.TPDO1_COUNTED`, it
makes every answer say which SYNC it answers, however late it arrives."""
SYNC_COUNTER_OVERFLOW = 0x1019
"""UNSIGNED8 (CiA 301): the SYNC counter's overflow value: 0, a SYNC without data; 2..240, every SYNC carries a
counter counting 1, 2, … up to this value, then from 1 again."""

# ----- values -------------------------------------------------------------------------------------------

DEVICE_TYPE_CIA402_SERVO = 0x0002_0192
"""0x1000 of a CiA 402 servo drive: profile number 402 (0x0192) in the low word, type 0x02 (servo) above."""

CIA402_PROFILE = 402
"""The low word of 0x1000 of any CiA 402 drive (servo, stepper, frequency converter)."""

LEG_DRIVE_VENDOR_ID = 0x0000_0000
"""0x1018 sub 1 of the project's leg drive (``leg_drive.eds``, the emulated drives)."""

LEG_DRIVE_PRODUCT_CODE = 0x534B_5401
"""0x1018 sub 2 of the project's leg drive ("SKT" and 1): with :data:`LEG_DRIVE_VENDOR_ID` it identifies a drive
whose manufacturer objects are 0x2010..0x2012 (``drivers.canopen.profiles``)."""

SYNC_COUNTER_MAX = 240
"""The largest SYNC counter overflow value CiA 301 allows (0x1019): the counter's period in SYNCs."""

MODE_CYCLIC_SYNCHRONOUS_POSITION = 8
"""0x6060/0x6061 value of cyclic synchronous position mode (CSP)."""

SUPPORTED_MODE_CSP = 1 << 7
"""0x6502 bit of CSP (bit = mode − 1)."""

SI_UNIT_MICROMETRE = 0xFA01_0000
"""0x60A8 value for µm: byte 3 prefix 10⁻⁶ (0xFA = −6), byte 2 unit metre (0x01), byte 1 no denominator."""

SI_UNIT_MICROMETRE_PER_SECOND = 0xFA01_0300
"""0x60A9 value for µm/s: as :data:`SI_UNIT_MICROMETRE` with denominator second (0x03) in byte 1."""

EMCY_FOLLOWING_ERROR = 0x8611
"""EMCY error code (CiA 402): following error beyond 0x6065."""
EMCY_REFERENCE_LIMIT = 0x8612
"""EMCY error code (CiA 402): reference limit (a target beyond 0x607D)."""
EMCY_HEARTBEAT_ERROR = 0x8130
"""EMCY error code (CiA 301): life guard or heartbeat error (the master's heartbeat went silent)."""
EMCY_SYNC_LOST = 0x8700
"""EMCY error code (CiA 402): sync controller (SYNC, and with it the setpoints, stopped coming)."""
EMCY_DEVICE_HARDWARE = 0x5000
"""EMCY error code (CiA 301): device hardware (a fault of the drive itself)."""

ERROR_REGISTER_GENERIC = 1 << 0
ERROR_REGISTER_COMMUNICATION = 1 << 4
ERROR_REGISTER_DEVICE_PROFILE = 1 << 5


def load_od(node_id: int) -> canopen.ObjectDictionary:
    """The leg drive's object dictionary for node ``node_id`` (1..127; ``$NODEID`` COB-IDs resolved)."""
    if isinstance(node_id, bool) or not isinstance(node_id, int) or not 1 <= node_id <= 127:
        raise ValueError(f"CANopen node id must be an integer in 1..127, got {node_id!r}")
    return canopen.import_od(str(EDS_PATH), node_id)


def heartbeat_consumer_entry(node_id: int, period_ms: int) -> int:
    """A 0x1016 entry: consume node ``node_id``'s heartbeat, fault when none came for ``period_ms`` ms.

    Layout (UNSIGNED32): bits 16..23 node id, bits 0..15 time [ms]; bits 24..31 zero. ``period_ms`` = 0
    disables the entry.
    """
    for name, value, high in (("node id", node_id, 127), ("heartbeat consumer time", period_ms, 0xFFFF)):
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= high:
            raise ValueError(f"{name} must be an integer in 0..{high}, got {value!r}")
    return node_id << 16 | period_ms


def decode_heartbeat_consumer_entry(entry: int) -> tuple[int, int]:
    """``(node_id, period_ms)`` of a 0x1016 entry (the inverse of :func:`heartbeat_consumer_entry`)."""
    if isinstance(entry, bool) or not isinstance(entry, int) or not 0 <= entry <= 0x007F_FFFF:
        raise ValueError(f"a heartbeat consumer entry has a node id 0..127 in bits 16..23 and bits 24..31 clear, "
                         f"got {entry!r}")
    return entry >> 16, entry & 0xFFFF
