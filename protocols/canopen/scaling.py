"""Leg length [m] ↔ drive position [increments], velocity [m/s] ↔ [increments/s].

Resolution: **1 increment = 1 µm** of joint-to-joint leg length (0x60A8 = µm), 1 increment/s = 1 µm/s
(0x60A9 = µm/s). Zero: position 0 is the leg's **minimum length** (rounded to the µm), so a position is the
actuator's extension and the software position limits 0x607D are ``(0, stroke)``:

    position = round(length × 10⁶) − round(leg_min × 10⁶)        length = (position + round(leg_min × 10⁶)) / 10⁶

Rounding is to the nearest increment (ties to even). A length that is a whole number of µm (as written in
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
    """The position scaling of a leg whose joint-to-joint length runs over [leg_min, leg_max] [m]."""

    leg_min: float
    leg_max: float

    def __post_init__(self) -> None:
        low, high = _finite(self.leg_min, "leg_min"), _finite(self.leg_max, "leg_max")
        if not 0 < low < high:
            raise LegRangeError(f"leg range must satisfy 0 < leg_min < leg_max, got [{low!r}, {high!r}] m")
        if round(high * INCREMENTS_PER_METRE) - round(low * INCREMENTS_PER_METRE) > _INT32[1]:
            raise LegRangeError(f"leg stroke {high - low!r} m does not fit an INTEGER32 position in µm")
        object.__setattr__(self, "leg_min", low)
        object.__setattr__(self, "leg_max", high)

    @property
    def _offset(self) -> int:
        return round(self.leg_min * INCREMENTS_PER_METRE)

    @property
    def stroke(self) -> int:
        """Position at ``leg_max`` [increments]."""
        return round(self.leg_max * INCREMENTS_PER_METRE) - self._offset

    @property
    def software_position_limits(self) -> tuple[int, int]:
        """0x607D sub 1 and sub 2 [increments]: ``(0, stroke)``."""
        return 0, self.stroke

    def position(self, length: float, leg: int | None = None) -> int:
        """Target position [increments] of leg length ``length`` [m]; :class:`LegRangeError` outside the range.

        ``leg`` (1..6) only names the leg in the error message.
        """
        what = "leg length" if leg is None else f"leg {leg} length"
        value = _finite(length, what)
        if not self.leg_min <= value <= self.leg_max:
            raise LegRangeError(f"{what} {value!r} m is outside the leg's range "
                                f"[{self.leg_min!r}, {self.leg_max!r}] m")
        return round(value * INCREMENTS_PER_METRE) - self._offset

    def length(self, position: int) -> float:
        """Leg length [m] of a drive position [increments] (any INTEGER32: actual positions may overshoot)."""
        return (_int32(position, "position") + self._offset) / INCREMENTS_PER_METRE

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
