"""The CiA 402 encodings of a drive's units: the position unit 0x60A8 and the interpolation time period 0x60C2.

**0x60A8 (SI unit position, UNSIGNED32).** Byte 3: the prefix, a power of ten as a signed byte (0xFA = −6: micro);
byte 2: the unit (0x01 metre, 0xB5 increments — what EPOS4 and Everest drives report, 0x00B50000); byte 1: the
denominator (0 for a position); byte 0: reserved. A position in metres with prefix p is ``10^-p`` units per metre
(µm: 10⁶); one in increments has no length of its own: its scale is the encoder's and the mechanics'
(``drivers.canopen.units``).

**0x60C2 (interpolation time period, RECORD).** Sub 1 the mantissa (UNSIGNED8, 0..255), sub 2 the index (INTEGER8):
the drive interpolates between two targets over ``mantissa × 10^index`` s, which must be the SYNC period.
"""

from __future__ import annotations

from typing import NamedTuple

UNIT_METRE = 0x01
"""0x60A8 byte 2: metre."""

UNIT_INCREMENTS = 0xB5
"""0x60A8 byte 2: increments (of the position encoder)."""

_PREFIXES = {-9: "n", -6: "µ", -3: "m", -2: "c", -1: "d", 0: ""}


class PositionUnit(NamedTuple):
    """A decoded 0x60A8: ``unit`` (byte 2), ``prefix`` (the power of ten, byte 3) and ``denominator`` (byte 1)."""

    unit: int
    prefix: int
    denominator: int

    @property
    def per_metre(self) -> float | None:
        """Units per metre of a length in metres (µm: 10⁶); None for increments or any other unit."""
        if self.unit != UNIT_METRE or self.denominator:
            return None
        return 10.0 ** -self.prefix

    @property
    def increments(self) -> bool:
        """Whether the unit is encoder increments (prefix 0, no denominator)."""
        return self.unit == UNIT_INCREMENTS and self.prefix == 0 and not self.denominator

    def __str__(self) -> str:
        if self.increments:
            return "increments"
        if self.per_metre is not None and self.prefix in _PREFIXES:
            return f"{_PREFIXES[self.prefix]}m"
        return f"unit 0x{self.unit:02X} × 10^{self.prefix}" + (f" per 0x{self.denominator:02X}"
                                                               if self.denominator else "")


def decode_position_unit(value: int) -> PositionUnit:
    """The position unit a 0x60A8 value states."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 0xFFFF_FFFF:
        raise ValueError(f"0x60A8 is an UNSIGNED32, got {value!r}")
    prefix = value >> 24
    return PositionUnit((value >> 16) & 0xFF, prefix - 256 if prefix >= 128 else prefix, (value >> 8) & 0xFF)


def encode_position_unit(unit: PositionUnit) -> int:
    """The 0x60A8 value of ``unit`` (the inverse of :func:`decode_position_unit`)."""
    return (unit.prefix & 0xFF) << 24 | unit.unit << 16 | unit.denominator << 8


def interpolation_period(period_us: int) -> tuple[int, int]:
    """0x60C2 ``(mantissa, index)`` of a SYNC period [µs]: the finest exact ``mantissa × 10^index`` s with a mantissa
    of at most 255 (2000 µs → (200, −5), 10 000 µs → (100, −4)); :class:`ValueError` when none is exact
    (3333 µs)."""
    if isinstance(period_us, bool) or not isinstance(period_us, int) or period_us < 1:
        raise ValueError(f"a SYNC period is a whole number of µs ≥ 1, got {period_us!r}")
    mantissa, index = period_us, -6
    while mantissa > 255 and mantissa % 10 == 0:
        mantissa, index = mantissa // 10, index + 1
    if mantissa > 255:
        raise ValueError(f"a SYNC period of {period_us} µs has no exact interpolation time period 0x60C2 "
                         "(mantissa 1..255 × 10^index s): choose a rate whose period has at most three significant "
                         "digits up to 255 (e.g. 500, 400, 250, 200 or 100 Hz)")
    return mantissa, index


def interpolation_seconds(mantissa: int, index: int) -> float:
    """The period [s] a 0x60C2 ``(mantissa, index)`` states."""
    return mantissa * 10.0 ** index
