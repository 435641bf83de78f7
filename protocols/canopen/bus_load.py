"""The SYNC cycle on the bus: bits per cycle, bus load of a setpoint rate, the cycle period object 0x1006.

Every cycle carries one SYNC (no counter: 0 data bytes) and, per axis, one RPDO1 and one TPDO1
(:mod:`protocols.canopen.pdo_maps`, 6 bytes each). Each frame is counted at its worst case: a CAN 2.0A data
frame (11-bit identifier) with ``n`` data bytes has 34 + 8n bits from start of frame to the end of the CRC,
where the transmitter may insert a stuff bit after every 4 after the first, then 13 bits that are never stuffed
(CRC delimiter, ACK slot and delimiter, end of frame) including the 3-bit interframe space:

    bits(n) = 8n + 47 + ⌊(34 + 8n − 1) / 4⌋          (55 for SYNC, 115 for a 6-byte PDO, 135 for 8 bytes)

(Davis, Burns, Bril, Lukkien 2007, "Controller Area Network (CAN) schedulability analysis: refuted, revisited
and revised", eq. 1). Six axes: 12 × 115 + 55 = 1435 bits per cycle, i.e. 143.5 % of a 1 Mbit/s bus at
1 kHz (does not fit at any limit) and 71.75 % at 500 Hz. The default limit, 80 %, leaves a fifth of the bus
for SDO, heartbeats, NMT, EMCY and the overturn detector's events; it admits up to 557 Hz with six axes at
1 Mbit/s, so the setpoint rate on CANopen is :data:`DEFAULT_RATE_HZ` = 500 Hz.

Plate accelerometers (:mod:`protocols.canopen.sensors`) add one 6-byte TPDO each to every cycle: with one,
1435 + 115 = 1550 bits, 77.5 % at 500 Hz (up to 516 Hz within the limit); two need 1665 bits, 83.25 % at 500 Hz,
over the limit (400 Hz: 66.6 %).

With the SYNC counter (``counted``: :data:`~protocols.canopen.pdo_maps.TPDO1_COUNTED`), SYNC carries a byte (65 bits)
and every TPDO one more (7 bytes: 125 bits): six axes and one accelerometer take 65 + 6 × 240 + 125 = 1630 bits,
81.5 % at 500 Hz (over the limit: the master then dates answers by their receive time) and 40.75 % at 250 Hz.
"""

from __future__ import annotations

import math
import numbers

from protocols.canopen.pdo_maps import RPDO1, TPDO1, TPDO1_COUNTED
from protocols.canopen.sensors import ACCEL_TPDO1, ACCEL_TPDO1_COUNTED

DEFAULT_RATE_HZ = 500
"""SYNC (setpoint) rate of the leg drives [Hz]."""

DEFAULT_LIMIT = 0.8
"""Largest fraction of the bitrate the cyclic traffic may take."""

SYNC_BYTES = 0
"""SYNC without a counter (0x1019 = 0)."""

COUNTED_SYNC_BYTES = 1
"""SYNC with its counter (0x1019 > 0)."""


class BusLoadError(ValueError):
    """A cycle that does not fit the bus."""


def frame_bits(data_bytes: int) -> int:
    """Worst-case length [bits] of a CAN 2.0A data frame with ``data_bytes`` (0..8), interframe space included."""
    if isinstance(data_bytes, bool) or not isinstance(data_bytes, int) or not 0 <= data_bytes <= 8:
        raise BusLoadError(f"a classic CAN frame carries 0..8 data bytes, got {data_bytes!r}")
    stuffed = 34 + 8 * data_bytes
    return stuffed + 13 + (stuffed - 1) // 4


def cycle_bits(axes: int, accelerometers: int = 0, counted: bool = False) -> int:
    """Worst-case bits of one SYNC cycle with ``axes`` drives and ``accelerometers`` plate accelerometers: SYNC, one
    RPDO1 and one TPDO1 per axis, one ACCEL_TPDO1 per accelerometer; ``counted``: SYNC with its counter and the
    TPDOs with the answered SYNC's (module docstring)."""
    if isinstance(axes, bool) or not isinstance(axes, int) or axes < 1:
        raise BusLoadError(f"axes must be a positive integer, got {axes!r}")
    if isinstance(accelerometers, bool) or not isinstance(accelerometers, int) or accelerometers < 0:
        raise BusLoadError(f"accelerometers must be a non-negative integer, got {accelerometers!r}")
    if counted:
        return (frame_bits(COUNTED_SYNC_BYTES) + axes * (frame_bits(RPDO1.size) + frame_bits(TPDO1_COUNTED.size))
                + accelerometers * frame_bits(ACCEL_TPDO1_COUNTED.size))
    return (frame_bits(SYNC_BYTES) + axes * (frame_bits(RPDO1.size) + frame_bits(TPDO1.size))
            + accelerometers * frame_bits(ACCEL_TPDO1.size))


def _positive(value: float, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value) or value <= 0:
        raise BusLoadError(f"{what} must be a positive number, got {value!r}")
    return float(value)


def bus_load(rate_hz: float, axes: int, bitrate: float, accelerometers: int = 0, counted: bool = False) -> float:
    """Fraction of ``bitrate`` [bit/s] the cycle takes at ``rate_hz`` [Hz] with ``axes`` drives and
    ``accelerometers`` (may exceed 1); ``counted`` as :func:`cycle_bits`."""
    return cycle_bits(axes, accelerometers, counted) * _positive(rate_hz, "rate_hz") / _positive(bitrate, "bitrate")


def max_rate_hz(axes: int, bitrate: float, limit: float = DEFAULT_LIMIT, accelerometers: int = 0) -> float:
    """Highest SYNC rate [Hz] whose bus load stays within ``limit``."""
    return _positive(limit, "limit") * _positive(bitrate, "bitrate") / cycle_bits(axes, accelerometers)


def check_bus_load(rate_hz: float, axes: int, bitrate: float, limit: float = DEFAULT_LIMIT,
                   accelerometers: int = 0) -> float:
    """The bus load of :func:`bus_load`; :class:`BusLoadError` naming the numbers when it exceeds ``limit``."""
    load = bus_load(rate_hz, axes, bitrate, accelerometers)
    if load > _positive(limit, "limit"):
        bits = cycle_bits(axes, accelerometers)
        sensors = f" and {accelerometers} accelerometer{'s' if accelerometers > 1 else ''}" if accelerometers else ""
        sensor_bits = f" + {accelerometers} × ACCEL_TPDO1 {frame_bits(ACCEL_TPDO1.size)}" if accelerometers else ""
        raise BusLoadError(
            f"{axes} axes{sensors} at {rate_hz:g} Hz need {bits * rate_hz:.0f} bit/s ({bits} bits per cycle: SYNC "
            f"{frame_bits(SYNC_BYTES)} + {axes} × (RPDO1 {frame_bits(RPDO1.size)} + TPDO1 {frame_bits(TPDO1.size)})"
            f"{sensor_bits}, worst-case bit stuffing), {load:.1%} of {bitrate:.0f} bit/s, over the {limit:.0%} "
            f"limit; the highest rate within it is {max_rate_hz(axes, bitrate, limit, accelerometers):.1f} Hz")
    return load


def cycle_period_us(rate_hz: float) -> int:
    """The communication cycle period 0x1006 [µs] of a SYNC rate; :class:`BusLoadError` unless whole µs."""
    period = 1e6 / _positive(rate_hz, "rate_hz")
    whole = round(period)
    if whole < 1 or abs(period - whole) > 1e-9 * period:
        raise BusLoadError(f"a SYNC rate of {rate_hz:g} Hz has a period of {period:g} µs, not a whole number of µs")
    return whole
