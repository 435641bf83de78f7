"""Sequence file → `Sequence`: types, keys, ranges and placements checked, with ``FILE:LINE: key`` errors.

What needs the records or the drives (a record that does not resolve, a body that cannot stand at an angle,
a drive outside the table) is checked by ``Sequence.check``; the layout of the file is in the package
docstring (`rig.sequence`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from collections.abc import Sequence as Seq
from dataclasses import replace
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from analysis.body import TABLE_V, Body
from analysis.table.limit_detectors import read_limit_detectors
from analysis.table.model import TableModel, TableModelError
from analysis.table.toml_check import TomlChecker, TomlFileError, read_toml, shown
from analysis.table.toml_lines import KeyPath, dotted_path, suggest
from rig.drive.prepare import FC_MAX, FC_MIN, HEADROOM_MAX
from rig.records.source import DT_MAX_S, DT_MIN_S, MAX_DURATION_S

from .model import (
    AS_RECORDED,
    DEFAULT_FRICTION,
    DEFAULT_PLATE,
    NEGATED,
    POLARITIES,
    DriveOptions,
    OperatorSteps,
    PlacedBody,
    RecordEntry,
    SequenceError,
    check_prompt,
)
from .records import expand_records_from, resolve_spec

SCHEMA = "shaketable-rig/sequence/1"
"""The ``schema`` written by ``Sequence.to_dict`` (a file may give it; it must then be this)."""

TOP_KEYS = ("name", "description", "table_url", "repetitions", "angles_deg", "polarity", "records", "records_from",
            "bodies", "rig", "plate", "drive", "operator", "schema", "source", "limit_detectors")
BODY_KEYS = ("body_id", "name", "table5", "b", "h", "depth", "mass", "b_cg", "h_cg", "x", "y", "friction",
             "restitution")
DIMENSIONS = ("b", "h", "depth", "mass")
RECORD_KEYS = ("record", "scale", "window_s", "corner_hz", "dt_s", "units", "drive", "polarity")
RECORDS_FROM_KEYS = ("suite", "strongest", "scale", "corner_hz", "polarity")
RIG_KEYS = ("config", "table", "limits", "hexapod", "dynamics", "controller", "limit_detectors")
_RIG_INLINE = "\x00rig"  # the source name given to TableModel.from_dict, to find its key in the message
TABLE_SCHEMES = ("mavlink", "zenoh", "canopen")
"""The table controllers' URL schemes (``drivers.open_table``)."""

#: Physical ranges of the sequence file's numbers: key → (low, high, the range in words). Bodies stand on a
#: plate of a few metres; a drive holds its tilt at most a minute; the high-pass corner is the drive
#: preparation's (``rig.drive.prepare.FC_MIN`` … ``FC_MAX``); record time steps and windows are the readers'.
RANGES: dict[str, tuple[float, float, str]] = {
    "b": (0.001, 3.0, "a base width from 0.001 m to 3 m"),
    "h": (0.001, 5.0, "a height from 0.001 m to 5 m"),
    "depth": (0.001, 3.0, "a depth from 0.001 m to 3 m"),
    "mass": (0.001, 2000.0, "a mass from 0.001 kg to 2000 kg"),
    "friction": (0.01, 2.0, "a friction coefficient μ from 0.01 to 2"),
    "size_m": (0.1, 10.0, "[x, y] in metres, each from 0.1 m to 10 m"),
    "settle_s": (0.0, 60.0, "a time from 0 s to 60 s"),
    "corner_hz": (FC_MIN, FC_MAX, f"a high-pass corner from {FC_MIN:g} Hz to {FC_MAX:g} Hz"),
    "scale": (0.001, 1.0, '"table" or a fixed factor from 0.001 to 1'),
    "dt_s": (DT_MIN_S, DT_MAX_S, f"a record time step from {DT_MIN_S:g} s to {DT_MAX_S:g} s"),
    "window_s": (0.0, MAX_DURATION_S, f"[t0, t1] in seconds of the record, 0 ≤ t0 < t1 ≤ {MAX_DURATION_S:g}"),
}
MAX_REPETITIONS = 100
"""Largest ``repetitions``."""
MAX_ITEMS = {"bodies": 100, "angles_deg": 100, "records": 1000}
"""Longest lists of a sequence file."""
MAX_RUNS = 10_000
"""Largest plan (angles x records x repetitions); the paper's campaign is 130 runs."""
MAX_TEXT = {"description": 10_000}
"""Longest strings [characters]: the description, else 1000."""


class _Reader(TomlChecker):
    """Checks a parsed sequence mapping; ``lines`` (from the TOML text) give the line of each key."""

    def __init__(self, source: str, lines: Mapping[KeyPath, int], base_dir: Path) -> None:
        super().__init__(source, lines)
        self.base_dir = base_dir
        self.default_polarity = AS_RECORDED

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
            raise self.error(path, f"expected {what}, got {shown(value)}")
        return x

    def quantity(self, value: Any, path: KeyPath, key: str) -> float:
        """A number in the physical range of ``key`` (`RANGES`)."""
        low, high, what = RANGES[key]
        return self.ranged(value, path, low, high, what)

    def items(self, value: Any, path: KeyPath, what: str) -> list[Any]:
        """A non-empty list of at most `MAX_ITEMS` items."""
        key = str(path[-1])
        if not isinstance(value, list) or not value:
            raise self.error(path, f"expected {what}, got {shown(value)}")
        if len(value) > MAX_ITEMS[key]:
            raise self.error(path, f"{len(value)} items; expected at most {MAX_ITEMS[key]}")
        return value

    def integer(self, value: Any, path: KeyPath, low: int, high: int | None = None) -> int:
        ok = isinstance(value, int) and not isinstance(value, bool) and value >= low \
            and (high is None or value <= high)
        if not ok:
            span = f"from {low} to {high}" if high is not None else f"≥ {low}"
            raise self.error(path, f"expected a whole number {span}, got {shown(value)}")
        return value

    def string(self, value: Any, path: KeyPath, *, empty: bool = False) -> str:
        if not isinstance(value, str) or (not empty and not value.strip()):
            raise self.error(path, f"expected a {'' if empty else 'non-empty '}string, got {shown(value)}")
        longest = MAX_TEXT.get(str(path[-1]) if path else "", 1000)
        if len(value) > longest:
            raise self.error(path, f"the text is {len(value):,} characters; expected at most {longest:,}")
        return value

    def boolean(self, value: Any, path: KeyPath) -> bool:
        if not isinstance(value, bool):
            raise self.error(path, f"expected true or false, got {value!r}")
        return value

    def pair(self, value: Any, path: KeyPath, what: str) -> tuple[float, float]:
        if not isinstance(value, list) or len(value) != 2:
            raise self.error(path, f"expected {what}, got {shown(value)}")
        return (self.number(value[0], (*path, 0), what=what), self.number(value[1], (*path, 1), what=what))

    def scale(self, value: Any, path: KeyPath) -> float | None:
        if value == "table":
            return None
        if isinstance(value, str):
            raise self.error(path, f"expected {RANGES['scale'][2]}, got {shown(value)}")
        return self.quantity(value, path, "scale")

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
        what = RANGES["size_m"][2]
        size = self.pair(plate["size_m"], (*path, "size_m"), what)
        return (self.quantity(size[0], (*path, "size_m", 0), "size_m"),
                self.quantity(size[1], (*path, "size_m", 1), "size_m"))

    def drive(self, value: Any) -> DriveOptions:
        path: KeyPath = ("drive",)
        drive = self.table(value, path, ("settle_s", "corner_hz", "headroom_pct"))
        options = DriveOptions()
        settle = options.settle
        if "settle_s" in drive:
            settle = self.quantity(drive["settle_s"], (*path, "settle_s"), "settle_s")
        corner = None
        if "corner_hz" in drive:
            corner = self.quantity(drive["corner_hz"], (*path, "corner_hz"), "corner_hz")
        headroom = options.headroom
        if "headroom_pct" in drive:
            headroom = self.ranged(drive["headroom_pct"], (*path, "headroom_pct"), 0.0, 100 * HEADROOM_MAX,
                                   "a percentage") / 100
        return DriveOptions(settle=settle, corner=corner, headroom=headroom)

    def operator(self, value: Any) -> OperatorSteps:
        path: KeyPath = ("operator",)
        steps = self.table(value, path, ("place_bodies", "confirm_before_run", "ask_detections"))
        defaults = OperatorSteps()
        prompt = defaults.place_bodies
        if "place_bodies" in steps:
            prompt = self.string(steps["place_bodies"], (*path, "place_bodies"))
            try:
                check_prompt(prompt)
            except ValueError as exc:
                raise self.error((*path, "place_bodies"), str(exc)) from None
        flags = {key: self.boolean(steps[key], (*path, key)) if key in steps else getattr(defaults, key)
                 for key in ("confirm_before_run", "ask_detections")}
        return OperatorSteps(place_bodies=prompt, **flags)

    def bodies(self, value: Any, plate: tuple[float, float]) -> tuple[PlacedBody, ...]:
        path: KeyPath = ("bodies",)
        value = self.items(value, path, "at least one [[bodies]] table")
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
            dims = {key: value for key, value in (("b", paper.b), ("h", paper.h), ("depth", paper.depth),
                                                  ("mass", paper.mass)) if value is not None}
            cg = {"b_cg": paper.b_cg, "h_cg": paper.h_cg}
            name = name or paper.name
        else:
            dims = {key: self.quantity(self.require(table, path, key, f"{RANGES[key][2]} (or table5 = N)"),
                                       (*path, key), key) for key in DIMENSIONS}
            cg = {"b_cg": None, "h_cg": None}
        # the centre of gravity: b_cg from the base's -x (uphill) corner, h_cg above the base (analysis.body);
        # given with table5 = N it replaces the paper's (a block mounted the other way round: b_cg = b − b_cg)
        for key, side, words in (("b_cg", "b", "from the base's -x (uphill) corner along +x"),
                                 ("h_cg", "h", "above the base")):
            if key in table:
                what = (f"the centre of gravity {words} in metres, inside the body: 0 < {key} < {side} = "
                        f"{dims[side]:g} m")
                value = self.number(table[key], (*path, key), low=0.0, what=what)
                if value >= dims[side]:
                    raise self.error((*path, key), f"expected {what}, got {shown(table[key])}")
                cg[key] = value
        place = {key: self.number(self.require(table, path, key, "a number in metres (plate frame, +x downhill)"),
                                  (*path, key), what="a finite number in metres") for key in ("x", "y")}
        friction = DEFAULT_FRICTION
        if "friction" in table:
            friction = self.quantity(table["friction"], (*path, "friction"), "friction")
        restitution = None
        if "restitution" in table:
            restitution = self.number(table["restitution"], (*path, "restitution"), low=0.0, high=1.0,
                                      what="the body's measured coefficient of restitution, in (0, 1]")
        body = Body(b=dims["b"], h=dims["h"], depth=dims.get("depth"), mass=dims.get("mass"),
                    name=name or f"body {body_id}", **cg)
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
        value = self.items(value, path, "a non-empty list of plate angles in degrees, e.g. [0, 5]")
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

    def polarity(self, value: Any, path: KeyPath) -> str:
        if value not in POLARITIES:
            raise self.error(path, f"expected one of {', '.join(repr(p) for p in POLARITIES)} (\"both\": each "
                             f"record also played negated), got {value!r}")
        return str(value)

    def with_polarity(self, entry: RecordEntry, polarity: str, path: KeyPath) -> list[RecordEntry]:
        """The entry as recorded, negated, or both in turn (``polarity``)."""
        if polarity == AS_RECORDED:
            return [entry]
        if entry.drive is not None:
            raise self.error(path, f"{entry.label()} plays a compensated drive file as it was iterated; expected "
                             "polarity = \"as recorded\" for it (iterate the negated record for the other sign)")
        negated = replace(entry, polarity=-1)
        return [negated] if polarity == NEGATED else [entry, negated]

    def records(self, top: Mapping[str, Any]) -> tuple[RecordEntry, ...]:
        if "polarity" in top:
            self.default_polarity = self.polarity(top["polarity"], ("polarity",))
        entries: list[RecordEntry] = []
        if "records" in top:
            value = top["records"]
            if not isinstance(value, list):
                raise self.error(("records",), f"expected a list of records, got {shown(value)}")
            if len(value) > MAX_ITEMS["records"]:
                raise self.error(("records",), f"{len(value)} records; expected at most {MAX_ITEMS['records']}")
            for i, item in enumerate(value):
                entries.extend(self.record(item, ("records", i)))
        if "records_from" in top:
            entries.extend(self.records_from(top["records_from"]))
        if not entries:
            raise self.error(("records",), "missing; expected records = [\"SUITE:NAME\", ...] or records_from = "
                             "{ suite = \"fema\", strongest = 25 }")
        seen: dict[tuple[Any, ...], str] = {}
        for entry in entries:
            key = (entry.resolved, entry.scale, entry.window, entry.corner, entry.drive, entry.polarity)
            if key in seen:
                raise SequenceError(self.source, entry.line, entry.key, f"{entry.label()} is already {seen[key]} "
                                    "with the same options; expected each record once (use repetitions)")
            seen[key] = entry.key
        return tuple(entries)

    def record(self, value: Any, path: KeyPath) -> list[RecordEntry]:
        """The entry, twice with polarity \"both\" (as recorded, then negated)."""
        key, line = dotted_path(path), self.line(path)
        if isinstance(value, str):
            spec = self.string(value, path)
            entry = RecordEntry(spec=spec, resolved=resolve_spec(spec, self.base_dir), key=key, line=line)
            return self.with_polarity(entry, self.default_polarity, path)
        table = self.table(value, path, RECORD_KEYS)
        spec = self.string(self.require(table, path, "record", '"SUITE:NAME", "library:NAME" or a record file'),
                           (*path, "record"))
        options: dict[str, Any] = {}
        if "scale" in table:
            options["scale"] = self.scale(table["scale"], (*path, "scale"))
        if "window_s" in table:
            what = RANGES["window_s"][2]
            t0, t1 = self.pair(table["window_s"], (*path, "window_s"), what)
            if not 0.0 <= t0 < t1 <= MAX_DURATION_S:
                raise self.error((*path, "window_s"), f"expected {what}, got {shown(table['window_s'])}")
            options["window"] = (t0, t1)
        if "corner_hz" in table:
            options["corner"] = self.quantity(table["corner_hz"], (*path, "corner_hz"), "corner_hz")
        if "dt_s" in table:
            options["dt"] = self.quantity(table["dt_s"], (*path, "dt_s"), "dt_s")
        if "units" in table:
            options["units"] = self.string(table["units"], (*path, "units"))
        if "drive" in table:
            drive = self.string(table["drive"], (*path, "drive"))
            if drive != "prepared":
                options["drive"] = str((self.base_dir / drive).resolve())
        polarity = self.default_polarity
        if "polarity" in table:
            polarity = self.polarity(table["polarity"], (*path, "polarity"))
        entry = RecordEntry(spec=spec, resolved=resolve_spec(spec, self.base_dir), key=key, line=line, **options)
        return self.with_polarity(entry, polarity, (*path, "polarity") if "polarity" in table else path)

    def records_from(self, value: Any) -> list[RecordEntry]:
        path: KeyPath = ("records_from",)
        table = self.table(value, path, RECORDS_FROM_KEYS)
        suite = self.string(self.require(table, path, "suite", '"fema", "fema-farfield", "fema-nearfield" or '
                                         '"library"'), (*path, "suite"))
        strongest = self.integer(table["strongest"], (*path, "strongest"), 1) if "strongest" in table else None
        scale = self.scale(table["scale"], (*path, "scale")) if "scale" in table else None
        corner = self.quantity(table["corner_hz"], (*path, "corner_hz"), "corner_hz") if "corner_hz" in table else None
        try:
            specs = expand_records_from(suite, strongest)
        except ValueError as exc:
            key = "strongest" if "strongest" in str(exc) and "strongest" in table else "suite"
            raise self.error((*path, key), str(exc)) from None
        polarity = self.default_polarity
        if "polarity" in table:
            polarity = self.polarity(table["polarity"], (*path, "polarity"))
        line = self.line(path)
        return [expanded for spec in specs for expanded in self.with_polarity(
            RecordEntry(spec=spec, resolved=spec, scale=scale, corner=corner, key="records_from", line=line),
            polarity, path)]

    def table_url(self, value: Any) -> str:
        """``mavlink://HOST:PORT``, ``zenoh://HOST:PORT/TABLE`` or ``canopen://CHANNEL?interface=NAME``."""
        url = self.string(value, ("table_url",))
        expected = ("expected mavlink://HOST:PORT, zenoh://HOST:PORT/TABLE or canopen://CHANNEL?interface=NAME, "
                    "e.g. mavlink://127.0.0.1:14600")
        try:
            parts = urlsplit(url)
            port = parts.port if parts.scheme in ("mavlink", "zenoh") else None
        except ValueError:
            raise self.error(("table_url",), f"{expected}; got {shown(url)} (a bad port)") from None
        if "://" not in url or parts.scheme not in TABLE_SCHEMES:
            raise self.error(("table_url",), f"{expected}; got {shown(url)} (schemes: {', '.join(TABLE_SCHEMES)})")
        if parts.scheme in ("mavlink", "zenoh") and (port is None or not parts.hostname):
            raise self.error(("table_url",), f"{expected}; got {shown(url)} (no HOST:PORT)")
        if parts.scheme == "mavlink" and parts.path not in ("", "/"):
            raise self.error(("table_url",), f"{expected}; got {shown(url)} (a mavlink URL has no path)")
        if parts.scheme == "canopen" and (not parts.netloc or "interface=" not in parts.query):
            raise self.error(("table_url",), f"{expected}; got {shown(url)} (no CHANNEL or interface)")
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
    if "limit_detectors" in top:  # the sequence's detectors replace the rig's of the same channel
        overrides = read_limit_detectors(reader, top["limit_detectors"], link_timeout_s=table.link.link_timeout_s)
        table = replace(table, detectors=table.detectors.overridden(overrides))
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
        "repetitions": reader.integer(top["repetitions"], ("repetitions",), 1, MAX_REPETITIONS)
        if "repetitions" in top else 1,
    }
    runs = len(fields["angles_deg"]) * len(fields["records"]) * fields["repetitions"]
    if runs > MAX_RUNS:
        raise reader.error(("repetitions",) if "repetitions" in top else ("records",), (
            f"the plan has {runs:,} runs ({len(fields['angles_deg'])} angles x {len(fields['records'])} records x "
            f"{fields['repetitions']} repetitions); expected at most {MAX_RUNS:,}"))
    return fields


def read_file(path: str | Path) -> tuple[dict[str, Any], dict[KeyPath, int]]:
    """The checked fields of a sequence file and the lines of its keys (only a regular file of at most 1 MiB is
    read: `analysis.table.toml_check.read_toml`)."""
    source = str(path)
    try:
        data, lines = read_toml(path, "a sequence file")
    except TomlFileError as exc:
        problem = "no such sequence file" if exc.problem == "no such file" else exc.problem
        raise SequenceError(source, exc.line, "", problem) from None
    base_dir = Path(path).expanduser().resolve().parent
    return read_mapping(data, source, lines, base_dir, Path(path).stem), lines
