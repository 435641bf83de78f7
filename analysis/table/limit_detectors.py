"""The ``[limit_detectors]`` table of the rig configuration (and of a sequence, which overrides it channel by
channel): warning and abort levels on what the table and the specimens *measure* (``docs/limits.md``).

```toml
[limit_detectors.accel.x]        # every plate accelerometer's x reading (specific force, plate frame)
warn_high_g = 0.4                # a level's key ends in its unit; any of the four levels may be left out
abort_high_g = 0.6
warn_low_g = -0.4
abort_low_g = -0.6
persistence = 3                  # samples past a level before it trips (1 … 10000; default 1)
action = "controlled_stop"       # what an abort level does: record, pause, controlled_stop, emergency_stop

[limit_detectors.tilt.angle]     # every body's tilt sensor
warn_high_deg = 20
```

Channels (:data:`CHANNELS`) and the units their levels may be given in:

- ``accel.x``, ``accel.y``, ``accel.z``: each plate accelerometer's axis, the specific force it reads (z reads
  +1 g at rest, x reads −g sin β on a plate tilted by β) — ``g`` or ``m_s2``;
- ``pose.surge``, ``pose.sway``, ``pose.heave`` (``m``, ``mm``) and ``pose.roll``, ``pose.pitch``, ``pose.yaw``
  (``deg``, ``rad``): the plate's pose as the controller's feedback reports it;
- ``velocity.surge`` … ``velocity.yaw``: its rate between consecutive statuses (``m_s``, ``mm_s``; ``deg_s``,
  ``rad_s``);
- ``tilt.angle``: each body's tilt sensor, relative to the plate, > 0 towards the low side (``deg``, ``rad``);
- ``leg.following_error``: each leg's following error as the controller's statuses report it, its commanded minus
  its measured length (``m``, ``mm``);
- ``link.age``: the age of the latest status, on the host's clock (``s``, ``ms``; high levels only, 0 … 10 s).

A **high** level is passed by a value above it, a **low** level by one below it; present levels must be ordered
``abort_low < warn_low < warn_high < abort_high``. A level trips when ``persistence`` consecutive samples are past
it, once per run. A warning only records; an abort level does the detector's ``action``. Every level has the
channel's physical range (:data:`CHANNELS`). Errors are ``FILE:LINE: limit_detectors.CHANNEL.KEY: problem``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from analysis.table.toml_check import TomlChecker, shown

G = 9.81
"""Standard gravity [m/s²] for levels given in g (as ``analysis.body.G``)."""

DEG = math.pi / 180.0

ACTIONS = ("record", "pause", "controlled_stop", "emergency_stop")
"""What an abort level may do: only record it; pause the sequence at the end of the run; stop the table at once
with its stop ramp (decelerate, home) and end the session; brake it (emergency stop)."""

LEVELS = ("abort_low", "warn_low", "warn_high", "abort_high")
"""The four levels in the order their values must rise."""

PERSISTENCE_MAX = 10_000
"""Largest persistence [samples]."""


@dataclass(frozen=True)
class Quantity:
    """What a channel measures: its ``units`` (key suffix → factor to SI), the SI unit's name, and the largest
    |level| [SI] a configuration may give."""

    name: str
    units: Mapping[str, float]
    si: str
    bound: float
    bound_text: str
    lows: bool = True
    """False: a quantity that only a high level makes sense on (levels above 0, up to ``bound``)."""


_ACCELERATION = Quantity("an acceleration", {"g": G, "m_s2": 1.0}, "m/s²", 20 * G, "±20 g (±196.2 m/s²)")
_LENGTH = Quantity("a length", {"m": 1.0, "mm": 1e-3}, "m", 2.0, "±2 m")
_ANGLE = Quantity("an angle", {"deg": DEG, "rad": 1.0}, "rad", math.pi / 2, "±90° (±1.571 rad)")
_SPEED = Quantity("a speed", {"m_s": 1.0, "mm_s": 1e-3}, "m/s", 5.0, "±5 m/s")
_AGE = Quantity("an age", {"s": 1.0, "ms": 1e-3}, "s", 10.0, "0 … 10 s (above 0)", lows=False)
_RATE = Quantity("an angular rate", {"deg_s": DEG, "rad_s": 1.0}, "rad/s", 2 * math.pi, "±360°/s (±6.283 rad/s)")

POSE_AXES = ("surge", "sway", "heave", "roll", "pitch", "yaw")
"""The pose's coordinates in the feedback's order."""

CHANNELS: dict[str, Quantity] = {
    **{f"accel.{axis}": _ACCELERATION for axis in "xyz"},
    **{f"pose.{axis}": _LENGTH if k < 3 else _ANGLE for k, axis in enumerate(POSE_AXES)},
    **{f"velocity.{axis}": _SPEED if k < 3 else _RATE for k, axis in enumerate(POSE_AXES)},
    "tilt.angle": _ANGLE,
    "leg.following_error": _LENGTH,
    "link.age": _AGE,
}
"""Every channel a detector may watch, with what it measures (module docstring)."""


@dataclass(frozen=True)
class Detector:
    """One channel's levels [SI: m/s², m, rad, m/s, rad/s; None: not set], ``persistence`` [samples] and the
    ``action`` of its abort levels; ``where`` (``FILE:LINE``) says where it was written."""

    channel: str
    abort_low: float | None = None
    warn_low: float | None = None
    warn_high: float | None = None
    abort_high: float | None = None
    persistence: int = 1
    action: str = "controlled_stop"
    where: str = field(default="", compare=False)

    def levels(self) -> list[tuple[str, float]]:
        """The set levels as (name, value [SI]) in :data:`LEVELS` order."""
        return [(name, value) for name in LEVELS if (value := getattr(self, name)) is not None]

    def to_dict(self) -> dict[str, Any]:
        """The detector's keys in SI units (the TOML layout)."""
        suffix = next(unit for unit, factor in CHANNELS[self.channel].units.items() if factor == 1.0)
        out: dict[str, Any] = {f"{name}_{suffix}": value for name, value in self.levels()}
        out["persistence"] = self.persistence
        out["action"] = self.action
        return out


@dataclass(frozen=True)
class LimitDetectors:
    """The ``[limit_detectors]`` table: one :class:`Detector` per channel watched (none by default)."""

    detectors: tuple[Detector, ...] = ()

    def overridden(self, others: LimitDetectors) -> LimitDetectors:
        """These detectors with ``others``' replacing those of the same channel (a sequence's overrides)."""
        mine = {d.channel: d for d in self.detectors}
        mine.update({d.channel: d for d in others.detectors})
        return LimitDetectors(tuple(mine.values()))

    def to_dict(self) -> dict[str, Any]:
        """The table in the TOML layout (``{"accel": {"x": {...}}}``)."""
        out: dict[str, Any] = {}
        for detector in self.detectors:
            group, member = detector.channel.split(".")
            out.setdefault(group, {})[member] = detector.to_dict()
        return out


def read_limit_detectors(checker: TomlChecker, value: Any, root: str = "limit_detectors",
                         link_timeout_s: float | None = None) -> LimitDetectors:
    """The ``[limit_detectors]`` table read by ``checker`` (the rig configuration's or a sequence's reader, under
    the key ``root``); errors (the checker's) name the line, the channel and the key. With ``link_timeout_s`` (the
    rig's ``[controller]``, s), a ``link.age`` level must be below it (the link is lost before it would trip)."""
    if value is None:
        return LimitDetectors()
    groups = sorted({channel.split(".")[0] for channel in CHANNELS})
    top = checker.table(value, (root,), groups)
    detectors = []
    for group, members in top.items():
        allowed = [channel.split(".")[1] for channel in CHANNELS if channel.startswith(f"{group}.")]
        for member, keys in checker.table(members, (root, group), allowed).items():
            detectors.append(_detector(checker, (root, group, member), f"{group}.{member}", keys, link_timeout_s))
    return LimitDetectors(tuple(detectors))


def _detector(checker: TomlChecker, path: tuple[str, ...], channel: str, value: Any,
              link_timeout_s: float | None = None) -> Detector:
    quantity = CHANNELS[channel]
    if not isinstance(value, Mapping):
        raise checker.error(path, f"expected a table of levels, got {shown(value)}")
    levels: dict[str, float] = {}
    for key, raw in value.items():
        if key in ("persistence", "action"):
            continue
        level = next((name for name in LEVELS if key.startswith(f"{name}_")), None)
        if level is None:
            raise checker.error((*path, key), f"unknown key; expected a level ({', '.join(LEVELS)}) with its unit "
                                              f"(e.g. {LEVELS[-1]}_{next(iter(quantity.units))}), persistence or "
                                              "action")
        if not quantity.lows and level.endswith("low"):
            raise checker.error((*path, key), f"{channel} takes no low level (a status is never too recent): "
                                              "expected warn_high or abort_high")
        unit = key.removeprefix(f"{level}_")
        if unit not in quantity.units:
            raise checker.error((*path, key), f"unit {unit!r} does not fit {channel}, {quantity.name}: expected "
                                              f"{' or '.join(f'{level}_{u}' for u in quantity.units)}")
        if level in levels:
            raise checker.error((*path, key), f"{level} is given twice (in two units)")
        factor = quantity.units[unit]
        si = checker.real(raw, (*path, key), f"a number in {unit}") * factor
        if not (math.isfinite(si) and abs(si) <= quantity.bound and (quantity.lows or si > 0)):
            raise checker.error((*path, key), f"expected {quantity.name} within {quantity.bound_text}, got "
                                              f"{shown(raw)}")
        if channel == "link.age" and link_timeout_s is not None and si >= link_timeout_s:
            raise checker.error((*path, key), f"{level} ({si:g} s) must be below [controller] link_timeout_s "
                                              f"({link_timeout_s:g} s): the link is lost, and the session ends, "
                                              "before it would trip")
        levels[level] = si
    if not levels:
        raise checker.error(path, f"no level: give at least one of {', '.join(LEVELS)} with its unit")
    given = [(name, levels[name]) for name in LEVELS if name in levels]
    for (low_name, low), (high_name, high) in itertools.pairwise(given):
        if not low < high:
            key = next(k for k in value if k.startswith(f"{high_name}_"))
            raise checker.error((*path, key), f"levels in the wrong order: {high_name} ({high:g} {quantity.si}) must "
                                              f"be above {low_name} ({low:g} {quantity.si}); expected abort_low < "
                                              "warn_low < warn_high < abort_high")
    persistence = value.get("persistence", 1)
    if isinstance(persistence, bool) or not isinstance(persistence, int) or not 1 <= persistence <= PERSISTENCE_MAX:
        raise checker.error((*path, "persistence"), f"expected a whole number of samples from 1 to "
                                                    f"{PERSISTENCE_MAX}, got {shown(persistence)}")
    action = value.get("action", "controlled_stop")
    if action not in ACTIONS:
        raise checker.error((*path, "action"), f"expected one of {', '.join(ACTIONS)}, got {shown(action)}")
    line = checker.line(path)
    where = f"{checker.source}:{line}" if line else checker.source
    return Detector(channel, levels.get("abort_low"), levels.get("warn_low"), levels.get("warn_high"),
                    levels.get("abort_high"), persistence, action, where)


def first_trip(past: np.ndarray, carry: int, persistence: int) -> tuple[int | None, int]:
    """Where ``persistence`` consecutive samples past a level are first complete in a batch.

    ``past`` (n,) bool: each sample beyond the level; ``carry``: consecutive samples past it at the end of the
    batches before. Returns (the index of the sample that completes the persistence, or None; the consecutive
    count at the batch's end, the next batch's ``carry``)."""
    n = len(past)
    if n == 0:
        return None, carry
    index = np.arange(n)
    last_clear = np.maximum.accumulate(np.where(past, -1, index))
    run = index - last_clear + np.where(last_clear < 0, carry, 0)
    hits = np.flatnonzero(run >= persistence)
    return (int(hits[0]) if len(hits) else None), int(run[-1])


def is_past(values: np.ndarray, threshold: float, level: str) -> np.ndarray:
    """Which of ``values`` are past ``threshold``: above it for a ``…high`` level, below it for a ``…low`` one."""
    return values > threshold if level.endswith("high") else values < threshold


class StatusVelocity:
    """The plate's velocity between consecutive statuses, as the ``velocity.*`` detectors see it, on the host and
    on the controller alike: the difference of consecutive poses over their time step (the first status of a run
    has none; statuses with no time step between them give none)."""

    def __init__(self) -> None:
        self._last: tuple[float, np.ndarray] | None = None

    def feed(self, t: np.ndarray, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The statuses' times ``t`` (k,) and poses ``pose`` (k, 6) (m, rad): the velocity samples' times (≤ k,)
        and values (≤ k, 6) (m/s, rad/s), each at the later status of its pair."""
        if self._last is not None:
            all_t = np.concatenate([[self._last[0]], t])
            all_pose = np.vstack([self._last[1], pose])
        else:
            all_t, all_pose = t, pose
        if len(t):
            self._last = (float(t[-1]), np.array(pose[-1], dtype=float))  # a copy: the caller may reuse pose
        dt = np.diff(all_t)
        steps = dt > 0
        return all_t[1:][steps], np.diff(all_pose, axis=0)[steps] / dt[steps, None]
