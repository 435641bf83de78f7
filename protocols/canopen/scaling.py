"""Leg length [m] ↔ drive position [drive units], velocity [m/s] ↔ [drive units/s]: the one place where metres
become what a drive is told.

Resolution: ``per_metre`` drive position units per metre of joint-to-joint leg length — by default
:data:`INCREMENTS_PER_METRE` (1 unit = 1 µm: the project's leg drives, 0x60A8 = µm); a drive in encoder increments
has its own (e.g. 4096 counts × 50:1 over a 5 mm lead: 40 960 000 per metre, ``drivers.canopen.units``). Polarity:
``+1`` when the drive's position grows as the leg extends, ``-1`` when it shrinks. Zero: position 0 is the leg's
**minimum length** (rounded to the unit), so a position is the actuator's extension (times the polarity) and the
software position limits 0x607D are ``(0, stroke)`` (``(−stroke, 0)`` with polarity −1):

    position = p · (round(length · k) − round(leg_min · k))        length = (p · position + round(leg_min · k)) / k

Rounding is to the nearest unit (ties to even). With k = 10⁶ a length that is a whole number of µm (as written in
decimal) maps to its exact integer and back to the same float. The leg range comes from the caller (the table
model's ``leg_min``/``leg_max``); this module imports nothing of ours.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass

INCREMENTS_PER_METRE = 1_000_000
"""Position increments per metre of leg length (1 increment = 1 µm)."""

_INT32 = (-(1 << 31), (1 << 31) - 1)


class LegRangeError(ValueError):
    """A leg length outside the leg's range, or a value that does not fit the drive's objects."""


def _finite(value: float, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise LegRangeError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def _int32(value: int, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not _INT32[0] <= value <= _INT32[1]:
        raise LegRangeError(f"{what} must be an INTEGER32, got {value!r}")
    return int(value)


@dataclass(frozen=True)
class LegScaling:
    """The position scaling of a leg whose joint-to-joint length runs over [leg_min, leg_max] [m]: ``per_metre``
    drive units per metre, ``polarity`` +1 or −1 (module docstring)."""

    leg_min: float
    leg_max: float
    per_metre: float = INCREMENTS_PER_METRE
    polarity: int = 1

    def __post_init__(self) -> None:
        low, high = _finite(self.leg_min, "leg_min"), _finite(self.leg_max, "leg_max")
        per_metre = _finite(self.per_metre, "per_metre")
        if not 0 < low < high:
            raise LegRangeError(f"leg range must satisfy 0 < leg_min < leg_max, got [{low!r}, {high!r}] m")
        if per_metre <= 0:
            raise LegRangeError(f"drive units per metre must be > 0, got {per_metre!r}")
        if self.polarity not in (1, -1) or isinstance(self.polarity, bool):
            raise LegRangeError(f"polarity must be 1 or -1, got {self.polarity!r}")
        if round(high * per_metre) > _INT32[1]:
            raise LegRangeError(f"leg length {high!r} m at {per_metre:g} units/m does not fit an INTEGER32 position")
        object.__setattr__(self, "leg_min", low)
        object.__setattr__(self, "leg_max", high)
        object.__setattr__(self, "per_metre", per_metre)

    @property
    def _offset(self) -> int:
        return round(self.leg_min * self.per_metre)

    @property
    def stroke(self) -> int:
        """Extension at ``leg_max`` [drive units, ≥ 0 whatever the polarity]."""
        return round(self.leg_max * self.per_metre) - self._offset

    @property
    def software_position_limits(self) -> tuple[int, int]:
        """0x607D sub 1 and sub 2 [drive units]: ``(0, stroke)``, ``(−stroke, 0)`` with polarity −1."""
        return (0, self.stroke) if self.polarity > 0 else (-self.stroke, 0)

    def distance(self, metres: float) -> int:
        """A length ``metres`` [m, ≥ 0] as drive units (a following-error window), to the nearest unit; it must fit
        an UNSIGNED32 object."""
        value = round(_finite(metres, "distance") * self.per_metre)
        if not 0 <= value <= 0xFFFF_FFFE:
            raise LegRangeError(f"distance {metres!r} m at {self.per_metre:g} units/m does not fit an UNSIGNED32")
        return value

    def speed(self, metres_per_second: float) -> int:
        """A speed ``metres_per_second`` [m/s, ≥ 0] as drive units/s (0x607F max profile velocity, UNSIGNED32)."""
        value = round(_finite(metres_per_second, "speed") * self.per_metre)
        if not 0 <= value <= 0xFFFF_FFFF:
            raise LegRangeError(f"speed {metres_per_second!r} m/s at {self.per_metre:g} units/m does not fit an "
                                "UNSIGNED32")
        return value

    def position(self, length: float, leg: int | None = None) -> int:
        """Target position [drive units] of leg length ``length`` [m]; :class:`LegRangeError` outside the range.

        ``leg`` (1..6) only names the leg in the error message.
        """
        what = "leg length" if leg is None else f"leg {leg} length"
        value = _finite(length, what)
        if not self.leg_min <= value <= self.leg_max:
            raise LegRangeError(f"{what} {value!r} m is outside the leg's range "
                                f"[{self.leg_min!r}, {self.leg_max!r}] m")
        return self.polarity * (round(value * self.per_metre) - self._offset)

    def length(self, position: int) -> float:
        """Leg length [m] of a drive position [drive units] (any INTEGER32: actual positions may overshoot)."""
        return (self.polarity * _int32(position, "position") + self._offset) / self.per_metre

    def positions(self, lengths: Sequence[float]) -> tuple[int, ...]:
        """:meth:`position` of each leg's length, legs numbered 1.. in order (as in the table model)."""
        return tuple(self.position(length, leg) for leg, length in enumerate(lengths, start=1))

    def lengths(self, positions: Sequence[int]) -> tuple[float, ...]:
        """:meth:`length` of each leg's position."""
        return tuple(self.length(position) for position in positions)


def velocity_increments(velocity: float) -> int:
    """Velocity [increments/s] (INTEGER32) of ``velocity`` [m/s], to the nearest increment/s.

    0x607F (max profile velocity, UNSIGNED32) takes the leg's speed limit this way (a positive value).
    """
    value = round(_finite(velocity, "velocity") * INCREMENTS_PER_METRE)
    if not _INT32[0] <= value <= _INT32[1]:
        raise LegRangeError(f"velocity {velocity!r} m/s does not fit an INTEGER32 in µm/s")
    return value


def velocity(increments_per_second: int) -> float:
    """Velocity [m/s] of a drive velocity [increments/s]."""
    return _int32(increments_per_second, "velocity") / INCREMENTS_PER_METRE
