"""The limit levels a table controller evaluates itself (``docs/limits.md``, On the controller): the abort
levels of the ``[limit_detectors]`` whose action stops the table, on the channels the controller measures, as
the host downloads them before a stream (one signed SET_LIMIT command per level) and as the controller reports a
trip.

A level travels as the two parameters every transport's command carries (MAVLink COMMAND_LONG's param1, param2 as
float32; zenoh's as float64): ``param1`` a whole number packing what the level is (:meth:`ControllerLevel.code`:
channel, side, action, persistence; < 2²¹, exact in a float32), ``param2`` the level [SI: m/s², m, rad, m/s,
rad/s]. ``param1 = 0`` clears every level. On MAVLink the level is rounded to float32 (a relative change below
6e-8).

Channels (:data:`CONTROLLER_CHANNELS`, codes from 1), as the host's detectors of the same name: ``accel.x``,
``accel.y``, ``accel.z`` (1–3: every plate accelerometer's axis, on every tick's sample); ``pose.surge`` …
``pose.yaw`` (4–9) and ``velocity.surge`` … ``velocity.yaw`` (10–15: between consecutive statuses);
``leg.following_error`` (16: every leg's) — these on the values of every status the controller sends, so a
persistence counts statuses as on the host. A trip's ``sensor`` is the accelerometer, the leg (1–6) or 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.table.limit_detectors import CHANNELS, PERSISTENCE_MAX, POSE_AXES, LimitDetectors

ACCEL_CHANNELS = ("accel.x", "accel.y", "accel.z")
"""The channels evaluated on every tick's accelerometer samples."""

STATUS_CHANNELS = (*(f"pose.{axis}" for axis in POSE_AXES), *(f"velocity.{axis}" for axis in POSE_AXES),
                   "leg.following_error")
"""The channels evaluated on the values of every status (the plate's measured pose, its velocity between
consecutive statuses, each leg's following error)."""

CONTROLLER_CHANNELS = (*ACCEL_CHANNELS, *STATUS_CHANNELS)
"""The channels a controller evaluates, in code order (code = index + 1)."""

STOPPING_ACTIONS = ("controlled_stop", "emergency_stop")
"""The actions a controller takes itself, in code order (code = index)."""

SIDES = ("abort_low", "abort_high")
"""The levels a controller evaluates, in code order (code = index)."""

_PERSISTENCE_SPAN = 16_384
"""Room for the persistence in the code (> :data:`PERSISTENCE_MAX`)."""

CLEAR_CODE = 0
"""``param1`` that clears every level."""


@dataclass(frozen=True)
class ControllerLevel:
    """One abort level on one controller channel: passed by a sample beyond ``threshold`` [SI] (above it for
    ``abort_high``, below it for ``abort_low``) ``persistence`` samples in a row; then ``action``."""

    channel: str
    side: str
    threshold: float
    persistence: int
    action: str

    def code(self) -> int:
        """``param1``: ``((channel code × 2 + side) × 2 + action) × 16384 + persistence``."""
        channel = CONTROLLER_CHANNELS.index(self.channel) + 1
        return (((channel * 2 + SIDES.index(self.side)) * 2 + STOPPING_ACTIONS.index(self.action))
                * _PERSISTENCE_SPAN + self.persistence)

    def params(self) -> tuple[float, float]:
        """The command's two parameters (module docstring)."""
        return float(self.code()), float(self.threshold)

    @classmethod
    def decode(cls, params: tuple[float, ...]) -> ControllerLevel:
        """The level two parameters carry; ValueError naming what is wrong (a code that packs no level, a level
        that is not finite)."""
        code, threshold = (*params, 0.0, 0.0)[:2]
        if not (np.isfinite(code) and code == int(code) and code > CLEAR_CODE):
            raise ValueError(f"limit level code {code!r}: expected a whole number above 0")
        rest, persistence = divmod(int(code), _PERSISTENCE_SPAN)
        rest, action = divmod(rest, 2)
        channel, side = divmod(rest, 2)
        if not 1 <= channel <= len(CONTROLLER_CHANNELS):
            raise ValueError(f"limit level code {int(code)}: channel {channel} is not one of 1…"
                             f"{len(CONTROLLER_CHANNELS)} ({', '.join(CONTROLLER_CHANNELS)})")
        if not 1 <= persistence <= PERSISTENCE_MAX:
            raise ValueError(f"limit level code {int(code)}: persistence {persistence} outside 1…{PERSISTENCE_MAX}")
        if not np.isfinite(threshold) or abs(threshold) > CHANNELS[CONTROLLER_CHANNELS[channel - 1]].bound:
            raise ValueError(f"limit level {threshold!r} is not a finite level within the channel's range")
        return cls(CONTROLLER_CHANNELS[channel - 1], SIDES[side], float(threshold), persistence,
                   STOPPING_ACTIONS[action])


def controller_levels(detectors: LimitDetectors) -> tuple[ControllerLevel, ...]:
    """The levels of ``detectors`` a controller evaluates: the abort levels of the detectors on
    :data:`CONTROLLER_CHANNELS` whose action stops the table."""
    return tuple(ControllerLevel(d.channel, side, value, d.persistence, d.action)
                 for d in detectors.detectors if d.channel in CONTROLLER_CHANNELS and d.action in STOPPING_ACTIONS
                 for side, value in d.levels() if side in SIDES)


@dataclass(frozen=True)
class ControllerTrip:
    """A controller's trip: ``level`` passed by ``sensor``'s sample ``value`` [SI] at ``t_ns`` [ns, controller
    time: the sample (tick or status) that completed the persistence]; the controller then did the level's action.
    ``sensor`` is the accelerometer (``accel.*``), the leg 1–6 (``leg.following_error``) or 0 (the plate's)."""

    t_ns: int
    sensor: int
    value: float
    level: ControllerLevel

    def instance(self, sensors: dict[int, str] | None = None) -> str:
        """The channel's instance as the host's detectors name it: ``accel.0.x`` (``sensors`` maps the
        accelerometer's number to its name), ``leg.3.following_error``, ``pose.heave``."""
        group, name = self.level.channel.split(".")
        if group == "accel":
            return f"accel.{(sensors or {}).get(self.sensor, str(self.sensor))}.{name}"
        if group == "leg":
            return f"leg.{self.sensor}.{name}"
        return self.level.channel
