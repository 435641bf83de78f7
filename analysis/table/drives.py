"""The ``[drives]`` table of the rig configuration: what the CANopen master must know of the leg drives that their
object dictionaries cannot tell it (``docs/table-controller.md``, *Real drives*).

```toml
[drives]
encoder_increments = 4096     # per motor revolution (checked against the drive's 0x608F)
gear_ratio = 50               # motor revolutions per driving-shaft revolution (0x6091)
feed_m = 0.005                # leg travel per driving-shaft revolution [m] (the screw's lead)
# increments_per_metre = 40960000   # or the scale itself: drive position units per metre of leg
polarity = 1                  # +1: the drive's position grows as the leg extends; -1: it shrinks
position_unit = "increments"  # what 0x60A8 must state: "increments", "m", "mm", "um" or "nm"
eds = "drives/everest.eds"    # the drives' EDS (relative to this file): which objects they have
target_delay_s = 0.002        # a target latched at SYNC n is reached this long after it (default one cycle)
feedback_delay_s = 0.0        # a reported position is this much older than its SYNC
sync_counter = false          # counted SYNCs (only drives whose profile echoes the counter)

[drives.leg.3]                # per leg (1..6): any of the per-leg keys above, and its CANopen node id
node_id = 3
polarity = -1
```

Per-leg keys (in ``[drives]`` for all six, in ``[drives.leg.N]`` for one): ``increments_per_metre`` or the three
factors ``encoder_increments``, ``gear_ratio``, ``feed_m`` (both: they must agree), ``polarity``,
``position_unit``, ``eds``; ``node_id`` only per leg (default: the leg's number). Without a scale the master
takes the one the drive states in metres (0x60A8 = µm: 10⁶ per metre) and refuses a drive in increments. Every
number has its physical range; errors are ``FILE:LINE: drives.KEY: problem``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from analysis.table.toml_check import TomlChecker, shown

LEGS = 6
"""Leg drives of the hexapod."""

POSITION_UNITS = {"increments": None, "m": 1.0, "mm": 1e3, "um": 1e6, "nm": 1e9}
"""The position units ``position_unit`` may name, with their units per metre (None: increments)."""

SCALE_RANGE = (1e3, 1e10)
"""Drive position units per metre a configuration may give (1 mm to 0.1 nm per unit)."""

_RANGES: dict[str, tuple[float, float, str]] = {
    "increments_per_metre": (*SCALE_RANGE, "a scale from 1e3 to 1e10 drive units per metre (1 mm to 0.1 nm each)"),
    "encoder_increments": (1.0, 1e9, "a count from 1 to 1e9 increments per motor revolution"),
    "gear_ratio": (1e-3, 1e4, "a ratio from 0.001 to 10000 motor revolutions per driving-shaft revolution"),
    "feed_m": (1e-5, 1.0, "a lead from 1e-5 m to 1 m per driving-shaft revolution"),
    "target_delay_s": (0.0, 2.0, "a time from 0 s to 2 s"),
    "feedback_delay_s": (0.0, 2.0, "a time from 0 s to 2 s"),
}
_FACTORS = ("encoder_increments", "gear_ratio", "feed_m")
_LEG_KEYS = ("increments_per_metre", *_FACTORS, "polarity", "position_unit", "eds")
_TABLE_KEYS = (*_LEG_KEYS, "target_delay_s", "feedback_delay_s", "sync_counter", "leg")
_NODE_IDS = (1, 126)
"""Node ids a leg drive may have (0x7F is the master's heartbeat)."""


@dataclass(frozen=True)
class LegDriveSettings:
    """One leg drive as the configuration describes it. ``per_metre`` [drive units/m] is None when the
    configuration gives no scale (the drive's SI unit decides); ``encoder_increments`` [per motor revolution],
    ``gear_ratio`` [motor rev per shaft rev] and ``feed_m`` [m per shaft rev] are None unless given; ``where`` says
    where it was written (``FILE:LINE: drives.leg.N``) for the master's messages."""

    node_id: int
    per_metre: float | None = None
    encoder_increments: float | None = None
    gear_ratio: float | None = None
    feed_m: float | None = None
    polarity: int = 1
    position_unit: str | None = None
    eds: Path | None = None
    where: str = field(default="", compare=False)


def _default_legs() -> tuple[LegDriveSettings, ...]:
    return tuple(LegDriveSettings(leg) for leg in range(1, LEGS + 1))


@dataclass(frozen=True)
class DriveSettings:
    """The ``[drives]`` table: the six legs' settings (leg k at index k − 1), the delays [s] to assume for drives
    whose profile does not state them (None: one cycle and 0), and whether counted SYNCs are asked for."""

    legs: tuple[LegDriveSettings, ...] = field(default_factory=_default_legs)
    target_delay_s: float | None = None
    feedback_delay_s: float | None = None
    sync_counter: bool = False

    def to_dict(self) -> dict[str, Any]:
        """The table in the TOML layout (every leg's settings spelled out per leg)."""
        out: dict[str, Any] = {key: value for key, value in (
            ("target_delay_s", self.target_delay_s), ("feedback_delay_s", self.feedback_delay_s)) if value is not None}
        out["sync_counter"] = self.sync_counter
        legs = {}
        for leg, settings in enumerate(self.legs, start=1):
            entry: dict[str, Any] = {"node_id": settings.node_id, "polarity": settings.polarity}
            for key, value in (("increments_per_metre", settings.per_metre),
                               ("encoder_increments", settings.encoder_increments),
                               ("gear_ratio", settings.gear_ratio), ("feed_m", settings.feed_m),
                               ("position_unit", settings.position_unit),
                               ("eds", None if settings.eds is None else str(settings.eds))):
                if value is not None:
                    entry[key] = value
            legs[str(leg)] = entry
        out["leg"] = legs
        return out


def read_drives(checker: TomlChecker, value: Any) -> DriveSettings:
    """The ``[drives]`` table of the rig configuration read by ``checker`` (its source file names the EDS files'
    directory); errors (the checker's) name the line and key."""
    if value is None:
        return DriveSettings()
    path = ("drives",)
    top = checker.table(value, path, _TABLE_KEYS)
    delays = {key: checker.ranged(top[key], (*path, key), *_RANGES[key][:2], _RANGES[key][2])
              for key in ("target_delay_s", "feedback_delay_s") if key in top}
    counted = top.get("sync_counter", False)
    if not isinstance(counted, bool):
        raise checker.error((*path, "sync_counter"), f"expected true or false, got {shown(counted)}")
    per_leg = checker.table(top.get("leg", {}), (*path, "leg"), tuple(str(k) for k in range(1, LEGS + 1)))
    shared = {key: top[key] for key in _LEG_KEYS if key in top}
    legs = []
    for leg in range(1, LEGS + 1):
        own_path = (*path, "leg", str(leg))
        own = checker.table(per_leg.get(str(leg), {}), own_path, ("node_id", *_LEG_KEYS))
        given = {key: (own[key], (*own_path, key)) if key in own else (shared[key], (*path, key))
                 for key in ("node_id", *_LEG_KEYS) if key in own or key in shared}
        where_path = own_path if str(leg) in per_leg else path
        line = checker.line(where_path)
        where = f"{checker.source}:{line}: {'.'.join(where_path)}" if line else f"{checker.source}: drives"
        legs.append(_leg(checker, leg, given, where))
    ids = [settings.node_id for settings in legs]
    for leg, node_id in enumerate(ids, start=1):
        if ids.index(node_id) != leg - 1:
            raise checker.error((*path, "leg", str(leg), "node_id"),
                                f"node id {node_id} is leg {ids.index(node_id) + 1}'s already")
    return DriveSettings(tuple(legs), delays.get("target_delay_s"), delays.get("feedback_delay_s"), counted)


def _leg(checker: TomlChecker, leg: int, given: Mapping[str, tuple[Any, tuple[str, ...]]],
         where: str) -> LegDriveSettings:
    """One leg's settings from its ``given`` keys (value, key path)."""
    numbers = {key: checker.ranged(raw, key_path, *_RANGES[key][:2], _RANGES[key][2])
               for key, (raw, key_path) in given.items() if key in _RANGES}
    node_id = leg
    if "node_id" in given:
        raw, key_path = given["node_id"]
        low, high = _NODE_IDS
        if isinstance(raw, bool) or not isinstance(raw, int) or not low <= raw <= high:
            raise checker.error(key_path, f"expected a CANopen node id from {low} to {high}, got {shown(raw)}")
        node_id = raw
    polarity = 1
    if "polarity" in given:
        raw, key_path = given["polarity"]
        if isinstance(raw, bool) or raw not in (1, -1):
            raise checker.error(key_path, f"expected 1 or -1, got {shown(raw)}")
        polarity = int(raw)
    unit = None
    if "position_unit" in given:
        raw, key_path = given["position_unit"]
        if raw not in POSITION_UNITS:
            raise checker.error(key_path, f"expected one of {', '.join(POSITION_UNITS)}, got {shown(raw)}")
        unit = raw
    eds = None
    if "eds" in given:
        raw, key_path = given["eds"]
        if not isinstance(raw, str) or not raw:
            raise checker.error(key_path, f"expected the path of an EDS file, got {shown(raw)}")
        eds = Path(checker.source).parent / raw
        if not eds.is_file():
            raise checker.error(key_path, f"no such EDS file {str(eds)!r}")
    factors = [key for key in _FACTORS if key in numbers]
    if factors and len(factors) < len(_FACTORS):
        missing = [key for key in _FACTORS if key not in numbers]
        raise checker.error(given[factors[0]][1], f"give all of {', '.join(_FACTORS)} (missing {', '.join(missing)})")
    per_metre: float | None = numbers.get("increments_per_metre")
    if factors:
        derived = numbers["encoder_increments"] * numbers["gear_ratio"] / numbers["feed_m"]
        scale_low, scale_high = SCALE_RANGE
        if not scale_low <= derived <= scale_high:
            raise checker.error(given["feed_m"][1], f"the factors make {derived:g} increments per metre; expected "
                                                    f"{_RANGES['increments_per_metre'][2]}")
        if per_metre is not None and not math.isclose(per_metre, derived, rel_tol=1e-9):
            raise checker.error(given["increments_per_metre"][1],
                                f"{per_metre:g} increments per metre disagrees with the factors' "
                                f"{numbers['encoder_increments']:g} × {numbers['gear_ratio']:g} / "
                                f"{numbers['feed_m']:g} m = {derived:g}")
        per_metre = derived
    unit_per_metre = POSITION_UNITS[unit] if unit is not None else None
    if unit_per_metre is not None and per_metre is not None and not math.isclose(per_metre, unit_per_metre,
                                                                                  rel_tol=1e-9):
        raise checker.error(given["position_unit"][1], f"position unit {unit} is {unit_per_metre:g} per metre, "
                                                       f"not the scale's {per_metre:g}")
    return LegDriveSettings(node_id, per_metre, numbers.get("encoder_increments"), numbers.get("gear_ratio"),
                            numbers.get("feed_m"), polarity, unit, eds, where)
