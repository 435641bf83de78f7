"""The plate's sensor nodes on the leg drives' bus: accelerometers and the overturn detector.

**Accelerometer** ``k`` (0, 1, …: the order of the plate's sensors) is node :data:`ACCELEROMETER_NODE_IDS`\\ ``[k]``
(0x21 + k), described by ``accelerometer.eds``. It measures the specific force ``f = Rᵀ (a − g)`` [m/s²] in its
own axes: the plate frame (x along the fall line, +x downhill, z up; at rest on a level plate ``(0, 0, +9.81)``)
for a sensor mounted along the plate's axes, else as its calibration sheet's ``axes`` say (the host turns it into
the plate frame: ``drivers.hub.Feedback.mount``). It transmits
:data:`ACCEL_TPDO1` on every SYNC (transmission type 1): x, y, z as INTEGER16 of :data:`FORCE_INCREMENT` = 1 mm/s²
(±32.767 m/s², beyond that the value saturates). The sample in the TPDO of a SYNC was taken :data:`SAMPLE_DELAY`
(0x2101, µs) before that SYNC. With the SYNC counter on, a master maps :data:`ACCEL_TPDO1_COUNTED` instead: the
sample, then the answered SYNC's counter :data:`ANSWERED_SYNC` (0x2102, UNSIGNED8; :mod:`protocols.canopen.pdo_maps`).

The **overturn detector** is node :data:`DETECTOR_NODE_ID` (0x30), ``overturn_detector.eds``. Its
:data:`EVENT_TPDO1` is event-driven (transmission type 254) and carries one overturn, little-endian:

=========  ==========  =========================================================================
object     type        meaning
=========  ==========  =========================================================================
0x2200:1   UNSIGNED16  event id, unique per power-up of the detector (wraps after 65535)
0x2200:2   UNSIGNED8   body id: the body's place in the run's bodies
0x2200:3   INTEGER8    direction: +1 towards the low side, −1 towards the high side
0x2200:4   INTEGER16   plate tilt (pitch) at the overturn, 1 increment = :data:`TILT_INCREMENT` = 10 µrad
0x2200:5   UNSIGNED16  age: how long before this frame the overturn happened, 1 increment = 100 µs
=========  ==========  =========================================================================

Every event is sent at once and again :data:`EVENT_REPEATS` times :data:`EVENT_REPEAT_PERIOD` apart with the
same event id (the master keeps the first copy); the age in each copy dates the overturn without a shared clock.

The detector also holds the **bodies on the plate** (``docs/table-controller.md``, Bodies on the plate), read by SDO:
:data:`BODY_COUNT` (0x2201, UNSIGNED8) the number of bodies, and body ``k`` (its id in overturn events) in the RECORD
:data:`BODY_RECORDS` ``+ k`` (0x2210 …, at most :data:`MAX_BODIES`), sub 1..5 REAL32: breadth b along the fall line,
height h, depth, and the centre of its base x, y on the plate [m] (zeros: the detector knows only the channel).

Bus load: an accelerometer's TPDO is cyclic (6 bytes, 115 bits at worst per SYNC) and counts in
:func:`protocols.canopen.bus_load.cycle_bits`; the detector's frames are events (four 8-byte frames of 135 bits per
overturn) and, with the heartbeats, fit the fifth of the bus the cyclic limit leaves.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Collection
from pathlib import Path
from typing import NamedTuple

import canopen

from protocols.canopen.pdo_maps import MappedObject, PdoError, PdoSpec

ACCELEROMETER_EDS_PATH = Path(__file__).with_name("accelerometer.eds")
"""The plate accelerometer's electronic data sheet."""

DETECTOR_EDS_PATH = Path(__file__).with_name("overturn_detector.eds")
"""The overturn detector's electronic data sheet."""

ACCELEROMETER_NODE_IDS = tuple(range(0x21, 0x29))
"""Node id of plate accelerometer 0, 1, … (at most eight)."""

DETECTOR_NODE_ID = 0x30
"""Node id of the overturn detector."""

SPECIFIC_FORCE = 0x2100
"""ARRAY, sub 1..3: specific force x, y, z [:data:`FORCE_INCREMENT`], INTEGER16."""
SAMPLE_DELAY = 0x2101
"""[µs]: the sample in a SYNC's TPDO was taken this long before that SYNC."""
ANSWERED_SYNC = 0x2102
"""UNSIGNED8, PDO-mappable: the counter of the SYNC the TPDO answers (0 when the SYNC carries none)."""
OVERTURN_EVENT = 0x2200
"""RECORD, sub 1..5: the last overturn event (module docstring)."""
BODY_COUNT = 0x2201
"""UNSIGNED8: the number of bodies on the plate (module docstring)."""
BODY_RECORDS = 0x2210
"""Body ``k`` is the RECORD at this index + ``k``, sub 1..5: b, h, depth, x, y [m] as REAL32."""
MAX_BODIES = 16
"""Most bodies the detector's object dictionary holds."""

FORCE_INCREMENT = 1e-3
"""Specific force per increment [m/s²]."""
TILT_INCREMENT = 1e-5
"""Tilt per increment [rad]."""
AGE_INCREMENT_NS = 100_000
"""Age per increment [ns]."""

EVENT_REPEATS = 3
"""An overturn event is sent again this many times ..."""
EVENT_REPEAT_PERIOD = 0.1
"""... this far apart [s]."""

_INT16 = (-(1 << 15), (1 << 15) - 1)


class ForceSample(NamedTuple):
    """ACCEL_TPDO1: specific force x, y, z [increments of 1 mm/s²]."""

    x: int
    y: int
    z: int


class CountedForceSample(NamedTuple):
    """ACCEL_TPDO1_COUNTED: specific force x, y, z [increments of 1 mm/s²] and the answered SYNC's counter."""

    x: int
    y: int
    z: int
    sync_counter: int


class EventRecord(NamedTuple):
    """EVENT_TPDO1: event id, body id, direction, tilt [increments of 10 µrad], age [increments of 100 µs]."""

    event_id: int
    body_id: int
    direction: int
    tilt: int
    age: int


ACCEL_TPDO1: PdoSpec[ForceSample] = PdoSpec(
    "ACCEL_TPDO1", receive=False, number=1, record=ForceSample,
    objects=tuple(MappedObject(SPECIFIC_FORCE, axis, 16, True) for axis in (1, 2, 3)))
"""Accelerometer → master on every SYNC: one sample of the specific force."""

ACCEL_TPDO1_COUNTED: PdoSpec[CountedForceSample] = PdoSpec(
    "ACCEL_TPDO1", receive=False, number=1, record=CountedForceSample,
    objects=(*ACCEL_TPDO1.objects, MappedObject(ANSWERED_SYNC, 0, 8, False)))
"""Accelerometer → master on every SYNC: one sample and the answered SYNC's counter."""

EVENT_TPDO1: PdoSpec[EventRecord] = PdoSpec(
    "EVENT_TPDO1", receive=False, number=1, record=EventRecord, transmission_type=254,
    objects=(MappedObject(OVERTURN_EVENT, 1, 16, False), MappedObject(OVERTURN_EVENT, 2, 8, False),
             MappedObject(OVERTURN_EVENT, 3, 8, True), MappedObject(OVERTURN_EVENT, 4, 16, True),
             MappedObject(OVERTURN_EVENT, 5, 16, False)))
"""Detector → master on each overturn (and its repetitions)."""


def _finite(value: float, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise PdoError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def _saturated(value: float, low: int, high: int) -> int:
    return min(max(round(value), low), high)


def encode_force(force: Collection[float]) -> ForceSample:
    """The sample of a specific force (x, y, z) [m/s²], each axis rounded to 1 mm/s² and saturated at ±32.767."""
    if len(force) != 3:
        raise PdoError(f"a specific force has 3 axes, got {len(force)}")
    x, y, z = (_saturated(_finite(v, "specific force") / FORCE_INCREMENT, *_INT16) for v in force)
    return ForceSample(x, y, z)


def decode_force(sample: ForceSample) -> tuple[float, float, float]:
    """The specific force (x, y, z) [m/s²] of a sample."""
    return sample.x * FORCE_INCREMENT, sample.y * FORCE_INCREMENT, sample.z * FORCE_INCREMENT


def event_record(event_id: int, body_id: int, direction: int, tilt: float, age_ns: int) -> EventRecord:
    """The record of an overturn: ``event_id`` (taken modulo 2¹⁶), ``body_id`` 0..255, ``direction`` ±1,
    ``tilt`` [rad] (saturated at ±0.32767 rad), ``age_ns`` ≥ 0 [ns] (saturated at 6.5535 s)."""
    if direction not in (-1, 1):
        raise PdoError(f"an overturn direction is +1 or -1, got {direction!r}")
    if isinstance(body_id, bool) or not isinstance(body_id, numbers.Integral) or not 0 <= body_id <= 255:
        raise PdoError(f"body id must be an integer in 0..255, got {body_id!r}")
    if isinstance(age_ns, bool) or not isinstance(age_ns, numbers.Integral) or age_ns < 0:
        raise PdoError(f"age must be a non-negative integer of ns, got {age_ns!r}")
    return EventRecord(int(event_id) % (1 << 16), int(body_id), int(direction),
                       _saturated(_finite(tilt, "tilt") / TILT_INCREMENT, *_INT16),
                       min(round(age_ns / AGE_INCREMENT_NS), (1 << 16) - 1))


def event_tilt(record: EventRecord) -> float:
    """The plate tilt [rad] of an event."""
    return record.tilt * TILT_INCREMENT


def event_age_ns(record: EventRecord) -> int:
    """How long before its frame the event happened [ns]."""
    return record.age * AGE_INCREMENT_NS


def load_accelerometer_od(node_id: int) -> canopen.ObjectDictionary:
    """The accelerometer's object dictionary for node ``node_id`` (1..127)."""
    return canopen.import_od(str(ACCELEROMETER_EDS_PATH), _node_id(node_id))


def load_detector_od(node_id: int = DETECTOR_NODE_ID) -> canopen.ObjectDictionary:
    """The overturn detector's object dictionary for node ``node_id`` (1..127)."""
    return canopen.import_od(str(DETECTOR_EDS_PATH), _node_id(node_id))


def _node_id(node_id: int) -> int:
    if isinstance(node_id, bool) or not isinstance(node_id, int) or not 1 <= node_id <= 127:
        raise ValueError(f"CANopen node id must be an integer in 1..127, got {node_id!r}")
    return node_id
