"""Sequence file → `Sequence`: types, keys, ranges and placements checked, with ``FILE:LINE: key`` errors.

What needs the records or the drives (a record that does not resolve, a body that cannot stand at an angle,
a drive outside the table) is checked by ``Sequence.check``; the layout of the file is in the package
docstring (`rig.sequence`).
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping
from collections.abc import Sequence as Seq
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from analysis.body import TABLE_V, Body
from analysis.table.model import TableModel, TableModelError
from analysis.table.toml_check import TomlChecker
from analysis.table.toml_lines import KeyPath, dotted_path, key_lines, suggest, syntax_message
from rig.drive.prepare import HEADROOM_MAX

from .model import (
    DEFAULT_FRICTION,
    DEFAULT_PLATE,
    PROMPT_FIELDS,
    DriveOptions,
    OperatorSteps,
    PlacedBody,
    RecordEntry,
    SequenceError,
)
from .records import expand_records_from, resolve_spec

SCHEMA = "shaketable-rig/sequence/1"
"""The ``schema`` written by ``Sequence.to_dict`` (a file may give it; it must then be this)."""

TOP_KEYS = ("name", "description", "table_url", "repetitions", "angles_deg", "records", "records_from", "bodies",
            "rig", "plate", "drive", "operator", "schema", "source")
BODY_KEYS = ("body_id", "name", "table5", "b", "h", "depth", "mass", "x", "y", "friction", "restitution")
DIMENSIONS = ("b", "h", "depth", "mass")
RECORD_KEYS = ("record", "scale", "window_s", "corner_hz", "dt_s", "units", "drive")
RECORDS_FROM_KEYS = ("suite", "strongest", "scale", "corner_hz")
RIG_KEYS = ("config", "table", "limits", "hexapod")
_RIG_INLINE = "\x00rig"  # the source name given to TableModel.from_dict, to find its key in the message


class _Reader(TomlChecker):
    """Checks a parsed sequence mapping; ``lines`` (from the TOML text) give the line of each key."""

    def __init__(self, source: str, lines: Mapping[KeyPath, int], base_dir: Path) -> None:
        super().__init__(source, lines)
        self.base_dir = base_dir

    def error(self, path: KeyPath, problem: str) -> SequenceError:
        line = self.line(path) if path else None
        if line is None and self.lines:
            line = 1  # a key missing at the top level: top-level keys belong at the top of the file
        return SequenceError(self.source, line, dotted_path(path), problem)

    def unknown_key_hint(self, path: KeyPath, key: str, allowed: Seq[str]) -> str:
        if path and key in TOP_KEYS:
            return (f" (a top-level key: in TOML every key after a [section] header belongs to that section, so "
                    f"write {key} before the first [section])")
        return suggest(key, allowed)

    # ----- typed values ----------------------------------------------------------------------------

    def require(self, table: Mapping[str, Any], path: KeyPath, key: str, expected: str) -> Any:
        if key not in table:
            raise self.error((*path, key), f"missing; expected {expected}")
        return table[key]

    def number(self, value: Any, path: KeyPath, *, low: float | None = None, high: float | None = None,
               low_open: bool = True, what: str = "a number") -> float:
        """A finite number, above ``low`` (or at it, unless ``low_open``) and at most ``high``."""
        x = self.real(value, path, what)
        bad = not math.isfinite(x) or (low is not None and (x <= low if low_open else x < low)) \
            or (high is not None and x > high)
        if bad:
            raise self.error(path, f"expected {what}, got {value!r}")
        return x

    def positive(self, value: Any, path: KeyPath, unit: str) -> float:
        return self.number(value, path, low=0.0, what=f"a finite number > 0 {unit}".rstrip())

    def integer(self, value: Any, path: KeyPath, low: int, high: int | None = None) -> int:
        ok = isinstance(value, int) and not isinstance(value, bool) and value >= low \
            and (high is None or value <= high)
        if not ok:
            span = f"from {low} to {high}" if high is not None else f"≥ {low}"
            raise self.error(path, f"expected a whole number {span}, got {value!r}")
        return value

    def string(self, value: Any, path: KeyPath, *, empty: bool = False) -> str:
        if not isinstance(value, str) or (not empty and not value.strip()):
            raise self.error(path, f"expected a {'' if empty else 'non-empty '}string, got {value!r}")
        return value

    def boolean(self, value: Any, path: KeyPath) -> bool:
        if not isinstance(value, bool):
            raise self.error(path, f"expected true or false, got {value!r}")
        return value

    def pair(self, value: Any, path: KeyPath, what: str) -> tuple[float, float]:
        if not isinstance(value, list) or len(value) != 2:
            raise self.error(path, f"expected {what}, got {value!r}")
        return (self.number(value[0], (*path, 0), what=what), self.number(value[1], (*path, 1), what=what))

    def scale(self, value: Any, path: KeyPath) -> float | None:
        if value == "table":
            return None
        if isinstance(value, str):
            raise self.error(path, f"expected \"table\" or a fixed factor in (0, 1], got {value!r}")
        return self.number(value, path, low=0.0, high=1.0, what='"table" or a fixed factor in (0, 1]')

    # ----- sections --------------------------------------------------------------------------------

    def rig(self, value: Any) -> TableModel:
        path: KeyPath = ("rig",)
        rig = self.table(value, path, RIG_KEYS)
        if "config" in rig:
            if len(rig) > 1:
                other = next(key for key in rig if key != "config")
                raise self.error((*path, other), "give either config = FILE or the configuration inline, not both")
            name = self.string(rig["config"], (*path, "config"))
            file = Path(name).expanduser()
            file = file if file.is_absolute() else self.base_dir / file
            try:
                return TableModel.from_toml(file)
            except TableModelError as exc:
                raise self.error((*path, "config"), f"the rig configuration is refused: {exc}") from None
        try:
            return TableModel.from_dict(rig, source=_RIG_INLINE)
        except TableModelError as exc:
            found = re.match(rf"{re.escape(_RIG_INLINE)}: ([\w.\-]+): (.*)$", str(exc), re.S)
            if found:
                raise self.error((*path, *found.group(1).split(".")), found.group(2)) from None
            raise self.error(path, str(exc).removeprefix(f"{_RIG_INLINE}: ")) from None

    def plate(self, value: Any) -> tuple[float, float]:
        path: KeyPath = ("plate",)
        plate = self.table(value, path, ("size_m",))
        if "size_m" not in plate:
            return DEFAULT_PLATE
        size = self.pair(plate["size_m"], (*path, "size_m"), "[x, y] in metres, each > 0")
        for k, side in enumerate(size):
            if side <= 0:
                raise self.error((*path, "size_m", k), f"expected [x, y] in metres, each > 0, got {side!r}")
        return size

    def drive(self, value: Any) -> DriveOptions:
        path: KeyPath = ("drive",)
        drive = self.table(value, path, ("settle_s", "corner_hz", "headroom_pct"))
        options = DriveOptions()
        settle = options.settle
        if "settle_s" in drive:
            settle = self.number(drive["settle_s"], (*path, "settle_s"), low=0.0, low_open=False,
                                 what="a number of seconds ≥ 0")
        corner = None
        if "corner_hz" in drive:
            corner = self.positive(drive["corner_hz"], (*path, "corner_hz"), "Hz")
        headroom = options.headroom
        if "headroom_pct" in drive:
            headroom = self.number(drive["headroom_pct"], (*path, "headroom_pct"), low=0.0, low_open=False,
                                   high=100 * HEADROOM_MAX, what=f"a percentage from 0 to {100 * HEADROOM_MAX:g}") / 100
        return DriveOptions(settle=settle, corner=corner, headroom=headroom)

    def operator(self, value: Any) -> OperatorSteps:
        path: KeyPath = ("operator",)
        steps = self.table(value, path, ("place_bodies", "confirm_before_run", "ask_detections"))
        defaults = OperatorSteps()
        prompt = defaults.place_bodies
        if "place_bodies" in steps:
            prompt = self.string(steps["place_bodies"], (*path, "place_bodies"))
            try:
                prompt.format(**dict.fromkeys(PROMPT_FIELDS, 0))
            except (KeyError, IndexError, ValueError) as exc:
                raise self.error((*path, "place_bodies"), f"bad placeholder {exc}; the prompt may use "
                                 f"{', '.join('{' + f + '}' for f in PROMPT_FIELDS)}") from None
        flags = {key: self.boolean(steps[key], (*path, key)) if key in steps else getattr(defaults, key)
                 for key in ("confirm_before_run", "ask_detections")}
        return OperatorSteps(place_bodies=prompt, **flags)

    def bodies(self, value: Any, plate: tuple[float, float]) -> tuple[PlacedBody, ...]:
        path: KeyPath = ("bodies",)
        if not isinstance(value, list) or not value:
            raise self.error(path, f"expected at least one [[bodies]] table, got {value!r}")
        placed = tuple(self.body(item, (*path, i), i + 1) for i, item in enumerate(value))
        names: dict[str, int] = {}
        for i, body in enumerate(placed):
            if body.name in names:
                raise self.error((*path, i, "name"), f"the name {body.name!r} is already body {names[body.name]}'s; "
                                 "expected a unique name per body")
            names[body.name] = body.body_id
        self.placements(placed, plate)
        return placed

    def body(self, value: Any, path: KeyPath, body_id: int) -> PlacedBody:
        table = self.table(value, path, BODY_KEYS)
        if "body_id" in table and self.integer(table["body_id"], (*path, "body_id"), 1) != body_id:
            raise self.error((*path, "body_id"), f"expected {body_id}: bodies are numbered from 1 in file order")
        name = self.string(table["name"], (*path, "name")) if "name" in table else None
        if "table5" in table:
            given = [key for key in DIMENSIONS if key in table]
            if given:
                raise self.error((*path, given[0]), "give either table5 = N or the dimensions b, h, depth, mass, "
                                 "not both")
            paper = TABLE_V[self.integer(table["table5"], (*path, "table5"), 1, len(TABLE_V)) - 1]
            dims = {"b": paper.b, "h": paper.h, "depth": paper.depth, "mass": paper.mass}
            name = name or paper.name
        else:
            units = {"b": "m", "h": "m", "depth": "m", "mass": "kg"}
            dims = {key: self.positive(self.require(table, path, key, f"a number > 0 {units[key]} (or table5 = N)"),
                                       (*path, key), units[key]) for key in DIMENSIONS}
        place = {key: self.number(self.require(table, path, key, "a number in metres (plate frame, +x downhill)"),
                                  (*path, key), what="a finite number in metres") for key in ("x", "y")}
        friction = DEFAULT_FRICTION
        if "friction" in table:
            friction = self.positive(table["friction"], (*path, "friction"), "")
        restitution = None
        if "restitution" in table:
            restitution = self.number(table["restitution"], (*path, "restitution"), low=0.0, high=1.0,
                                      what="the body's measured coefficient of restitution, in (0, 1]")
        body = Body(b=dims["b"], h=dims["h"], depth=dims["depth"], mass=dims["mass"], name=name or f"body {body_id}")
        return PlacedBody(body_id=body_id, body=body, x=place["x"], y=place["y"], friction=friction,
                          restitution=restitution)

    def placements(self, bodies: tuple[PlacedBody, ...], plate: tuple[float, float]) -> None:
        """Every base inside the plate, no two bases overlapping (touching is allowed)."""
        half = (0.5 * plate[0], 0.5 * plate[1])
        for i, body in enumerate(bodies):
            x0, x1, y0, y1 = body.footprint()
            for key, low, high, h in (("x", x0, x1, half[0]), ("y", y0, y1, half[1])):
                if low < -h or high > h:
                    raise self.error(("bodies", i, key), (
                        f"body {body.body_id} ({body.name}) does not fit on the plate: its base spans {key} = "
                        f"{low:.4g} … {high:.4g} m, expected within ±{h:g} m (plate {plate[0]:g} x {plate[1]:g} m, "
                        "[plate] size_m)"))
            for j, other in enumerate(bodies[:i]):
                a0, a1, b0, b1 = other.footprint()
                if x0 < a1 and a0 < x1 and y0 < b1 and b0 < y1:
                    raise self.error(("bodies", i, "x"), (
                        f"body {body.body_id} ({body.name}) overlaps body {other.body_id} ({other.name}) on the "
                        f"plate: bases x {x0:.4g} … {x1:.4g}, y {y0:.4g} … {y1:.4g} m and x {a0:.4g} … {a1:.4g}, "
                        f"y {b0:.4g} … {b1:.4g} m (bodies[{j + 1}]); expected bases apart"))

    def angles(self, value: Any, table: TableModel) -> tuple[float, ...]:
        path: KeyPath = ("angles_deg",)
        if not isinstance(value, list) or not value:
            raise self.error(path, f"expected a non-empty list of plate angles in degrees, e.g. [0, 5], got {value!r}")
        limit = math.degrees(table.limits.tilt.angle)
        angles: list[float] = []
        for i, item in enumerate(value):
            what = f"an angle in degrees from 0 to the table's tilt limit {limit:g}°"
            angle = self.number(item, (*path, i), low=0.0, low_open=False, high=limit * (1 + 1e-12), what=what)
            if angle in angles:
                raise self.error((*path, i), f"{angle:g}° is already angles_deg[{angles.index(angle) + 1}]; "
                                 "expected each angle once (use repetitions to repeat runs)")
            angles.append(angle)
        return tuple(angles)

    def records(self, top: Mapping[str, Any]) -> tuple[RecordEntry, ...]:
        entries: list[RecordEntry] = []
        if "records" in top:
            value = top["records"]
            if not isinstance(value, list):
                raise self.error(("records",), f"expected a list of records, got {value!r}")
            entries.extend(self.record(item, ("records", i)) for i, item in enumerate(value))
        if "records_from" in top:
            entries.extend(self.records_from(top["records_from"]))
        if not entries:
            raise self.error(("records",), "missing; expected records = [\"SUITE:NAME\", ...] or records_from = "
                             "{ suite = \"fema\", strongest = 25 }")
        seen: dict[tuple[Any, ...], str] = {}
        for entry in entries:
            key = (entry.resolved, entry.scale, entry.window, entry.corner, entry.drive)
            if key in seen:
                raise SequenceError(self.source, entry.line, entry.key, f"{entry.label()} is already {seen[key]} "
                                    "with the same options; expected each record once (use repetitions)")
            seen[key] = entry.key
        return tuple(entries)

    def record(self, value: Any, path: KeyPath) -> RecordEntry:
        where = {"key": dotted_path(path), "line": self.line(path)}
        if isinstance(value, str):
            spec = self.string(value, path)
            return RecordEntry(spec=spec, resolved=resolve_spec(spec, self.base_dir), **where)
        table = self.table(value, path, RECORD_KEYS)
        spec = self.string(self.require(table, path, "record", '"SUITE:NAME", "library:NAME" or a record file'),
                           (*path, "record"))
        options: dict[str, Any] = {}
        if "scale" in table:
            options["scale"] = self.scale(table["scale"], (*path, "scale"))
        if "window_s" in table:
            what = "[t0, t1] in seconds of the record, 0 ≤ t0 < t1"
            t0, t1 = self.pair(table["window_s"], (*path, "window_s"), what)
            if not 0.0 <= t0 < t1:
                raise self.error((*path, "window_s"), f"expected {what}, got {table['window_s']!r}")
            options["window"] = (t0, t1)
        if "corner_hz" in table:
            options["corner"] = self.positive(table["corner_hz"], (*path, "corner_hz"), "Hz")
        if "dt_s" in table:
            options["dt"] = self.positive(table["dt_s"], (*path, "dt_s"), "s")
        if "units" in table:
            options["units"] = self.string(table["units"], (*path, "units"))
        if "drive" in table:
            drive = self.string(table["drive"], (*path, "drive"))
            if drive != "prepared":
                options["drive"] = str((self.base_dir / drive).resolve())
        return RecordEntry(spec=spec, resolved=resolve_spec(spec, self.base_dir), **options, **where)

    def records_from(self, value: Any) -> list[RecordEntry]:
        path: KeyPath = ("records_from",)
        table = self.table(value, path, RECORDS_FROM_KEYS)
        suite = self.string(self.require(table, path, "suite", '"fema", "fema-farfield", "fema-nearfield" or '
                                         '"library"'), (*path, "suite"))
        strongest = self.integer(table["strongest"], (*path, "strongest"), 1) if "strongest" in table else None
        scale = self.scale(table["scale"], (*path, "scale")) if "scale" in table else None
        corner = self.positive(table["corner_hz"], (*path, "corner_hz"), "Hz") if "corner_hz" in table else None
        try:
            specs = expand_records_from(suite, strongest)
        except ValueError as exc:
            key = "strongest" if "strongest" in str(exc) and "strongest" in table else "suite"
            raise self.error((*path, key), str(exc)) from None
        line = self.line(path)
        return [RecordEntry(spec=spec, resolved=spec, scale=scale, corner=corner, key="records_from", line=line)
                for spec in specs]

    def table_url(self, value: Any) -> str:
        url = self.string(value, ("table_url",))
        if "://" not in url or not urlsplit(url).scheme:
            raise self.error(("table_url",), f"expected a table URL scheme://…, e.g. mavlink://127.0.0.1:14600, "
                             f"got {url!r}")
        return url


def read_mapping(data: Mapping[str, Any], source: str, lines: Mapping[KeyPath, int], base_dir: Path,
                 default_name: str) -> dict[str, Any]:
    """The checked fields of a `Sequence` from a parsed file or a ``to_dict`` mapping."""
    reader = _Reader(source, lines, base_dir)
    top = reader.table(data, (), TOP_KEYS)
    if "schema" in top and top["schema"] != SCHEMA:
        raise reader.error(("schema",), f"expected {SCHEMA!r}, got {top['schema']!r}")
    if "source" in top:
        reader.string(top["source"], ("source",), empty=True)
    table = reader.rig(top["rig"]) if "rig" in top else TableModel()
    plate = reader.plate(top["plate"]) if "plate" in top else DEFAULT_PLATE
    fields: dict[str, Any] = {
        "name": reader.string(top["name"], ("name",)) if "name" in top else default_name,
        "description": reader.string(top["description"], ("description",), empty=True)
        if "description" in top else "",
        "table_url": reader.table_url(top["table_url"]) if "table_url" in top else None,
        "table": table,
        "plate": plate,
        "drive": reader.drive(top["drive"]) if "drive" in top else DriveOptions(),
        "operator": reader.operator(top["operator"]) if "operator" in top else OperatorSteps(),
        "bodies": reader.bodies(reader.require(top, (), "bodies", "[[bodies]] tables"), plate),
        "angles_deg": reader.angles(reader.require(top, (), "angles_deg", "a list of plate angles in degrees, "
                                                   "e.g. angles_deg = [0, 5]"), table),
        "records": reader.records(top),
        "repetitions": reader.integer(top["repetitions"], ("repetitions",), 1) if "repetitions" in top else 1,
    }
    return fields


def read_file(path: str | Path) -> tuple[dict[str, Any], dict[KeyPath, int]]:
    """The checked fields of a sequence file and the lines of its keys."""
    source = str(path)
    try:
        text = Path(path).read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise SequenceError(source, None, "", "no such sequence file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SequenceError(source, None, "", f"cannot read the sequence file: {exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        message = syntax_message(source, text, str(exc))
        found = re.match(rf"{re.escape(source)}:(\d+): (.*)$", message, re.S)
        if found:
            raise SequenceError(source, int(found.group(1)), "", found.group(2)) from None
        raise SequenceError(source, None, "", message.removeprefix(f"{source}: ")) from None
    lines = key_lines(text)
    base_dir = Path(path).expanduser().resolve().parent
    return read_mapping(data, source, lines, base_dir, Path(path).stem), lines
