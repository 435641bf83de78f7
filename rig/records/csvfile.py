"""Reader for CSV records (``.csv``): a header row naming the columns, then one sample a row.

::

    # dt = 0.005 s                      <- optional settings before or among the rows (see `settings`)
    time_s,acc_h_g,acc_h2_g,acc_v_g     <- header row
    0.000,0.0012,-0.0004,0.0001
    0.005,0.0020,-0.0011,0.0003

Cells are separated by commas (quoted cells allowed); blank lines and ``#`` comment lines are skipped.

Column names (case-insensitive; spaces and ``-`` count as ``_``):

* time [s]: ``t`` or ``time``;
* first horizontal acceleration (required): ``acc``, ``accel``, ``acceleration``, ``h``, ``h1``, or
  ``acc_h``/``acc_h1`` (prefix ``acc_``, ``accel_`` or ``acceleration_``);
* second horizontal acceleration: ``h2`` or ``acc_h2`` (same prefixes);
* vertical acceleration: ``v``, ``up``, ``acc_v``, ``acc_up`` (same prefixes);
* or SEED channel codes, with or without a location code (`component`): ``HN1``, ``HN2``, ``HNZ``,
  ``HNE.00``: the horizontal ones are the first and second horizontal in column order, ``Z`` (or ``3``) the
  vertical; one of another orientation (``HNA``) is refused.

A name may carry its unit in brackets, ``t [s]``, ``acceleration [cm/s2]``, ``acc_v (g)``, or as an
underscore suffix, ``time_s``, ``acc_g``, ``acc_h2_cm_s2``, ``acc_gal`` (units in `units`; the time unit
is ``s``). All acceleration columns share one unit, from their names, a ``# units = …`` setting or the
caller (``--units``); where several say it, they must agree. With a time column, dt comes from it (evenly
spaced within 1 % of dt, see `grid`); without one, from a ``# dt = …`` setting or the caller (``--dt``).
Any other column name is an error (a column is never silently ignored). A ``# npts = …`` setting is
checked against the rows, which catches a file cut off at the end of a line.

A one-component file's component comes from its column name (``acc_h``, ``h1``, ``HN1`` say horizontal); a
bare ``acc`` column says nothing, so the file name is read (``….HNZ.csv``), else a `RecordWarning` says the
component is unknown.

Memory: a file of ASCII text with LF or CR LF line breaks whose rows are all plain numbers (no quotes, no ``D``
exponent) is parsed from its bytes by numpy, a chunk at a time, straight into one array per column, never one Python
object per cell (``benchmarks/record_memory.py`` measures the peak per sample: the file's bytes and 8 bytes a column).
Any other file is read row by row with the exact checks, which either give the same arrays or stop at the first bad
cell with its ``FILE:LINE`` error. At most `source.MAX_SAMPLES` rows: they are counted before a cell is parsed.
"""

from __future__ import annotations

import csv
import math
import re
from array import array
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .component import HORIZONTAL, VERTICAL, component, from_name, name_component, seed_word
from .grid import time_step
from .motion import GroundMotion, array_sha256
from .settings import Settings, check_npts, is_comment, read_settings
from .source import (
    MAX_ABS_G,
    MAX_SAMPLES,
    DataLines,
    TextSource,
    agreed_dt,
    agreed_unit,
    byte_lines,
    comment_lines,
    count_rows,
    csv_ready,
    first_data_line,
    given_dt,
    line_count,
    line_number,
    located,
    matching_dt,
    parse_rows,
    read_record,
    source_from,
    strict_rows,
)
from .units import TO_G, given_unit, parse_unit

_EXPECTED = "a CSV record: a header row such as 'time_s,acc_g' and one sample a row"
_COLUMN_HELP = (
    "expected t/time [s] and acc (or acc_h), acc_h2, acc_v, each with an optional unit "
    "(e.g. 'time_s,acc_g' or 't [s],acceleration [cm/s2]')"
)
_CHANNEL_NAMES = {"h": "first horizontal", "h2": "second horizontal", "v": "vertical", "t": "time"}
_BARE = {"acc": "h", "accel": "h", "acceleration": "h", "t": "t", "time": "t"}
_SUFFIXES = {"h": "h", "h1": "h", "h2": "h2", "v": "v", "up": "v"}
_PREFIXES = ("acc_", "accel_", "acceleration_")
_BRACKET_RE = re.compile(r"(?P<name>[^\[\(]*?)\s*[\[\(](?P<unit>[^\]\)]*)[\]\)]")
_TIME_UNITS = ("s", "sec", "second", "seconds")
_PREFIX_PARTS = 2


@dataclass(frozen=True)
class _Column:
    """A named column: its channel (``t``, ``h``, ``h2``, ``v``) and its unit as written (or None)."""

    channel: str
    unit_text: str | None
    said_by: str | None = None
    """How the name states its component (``CSV column 'HN1', SEED channel …``), None for a bare ``acc``."""


def _channel(name: str) -> str | None:
    """The channel a column name (normalised, without unit) stands for, or None."""
    if name in _BARE:
        return _BARE[name]
    seed = seed_word(name)
    if seed is not None:
        return {HORIZONTAL: "seed_h", VERTICAL: "v"}.get(seed[0], "seed_unknown")
    for prefix in _PREFIXES:
        if name.startswith(prefix):
            name = name.removeprefix(prefix)
            break
    return _SUFFIXES.get(name)


def _is_unit(channel: str, text: str) -> bool:
    """True if ``text`` is a unit a column of ``channel`` may carry."""
    return text.strip().lower() in _TIME_UNITS if channel == "t" else parse_unit(text) is not None


def _column(src: TextSource, line: int, index: int, cell: str) -> _Column:
    """Parse one header cell (see the module docstring)."""
    bracket = _BRACKET_RE.fullmatch(cell.strip())
    name, unit_text = (bracket["name"], bracket["unit"].strip()) if bracket else (cell, None)
    name = re.sub(r"[\s\-]+", "_", name.strip().lower())
    channel, matched = _channel(name), name
    if channel is None and unit_text is None:
        parts = name.split("_", _PREFIX_PARTS)  # a channel name has at most 2 parts (acc_h2): linear in the cell
        for cut in range(1, len(parts)):
            prefix, suffix = "_".join(parts[:cut]), "_".join(parts[cut:])
            channel = _channel(prefix)
            if channel is not None and _is_unit(channel, suffix):
                unit_text, matched = suffix, prefix
                break
            channel = None
    if channel is None:
        raise src.error(line, f"column {index + 1}, {cell!r}, is not a record column; {_COLUMN_HELP}")
    seed = seed_word(matched)
    if channel == "seed_unknown":
        raise src.error(line, f"column {index + 1}, {cell!r}, is {seed[1] if seed else 'a SEED channel'}; expected a "
                              "horizontal (N, E, 1, 2) or vertical (Z, 3) channel")
    if unit_text is not None and not _is_unit(channel, unit_text):
        wanted = "s" if channel == "t" else "an acceleration unit"
        raise src.error(line, f"column {index + 1}, {cell!r}: unknown unit {unit_text!r}; expected {wanted}")
    said_by = None
    if channel != "t" and matched not in _BARE:
        said_by = f"CSV column {cell!r}" + (f", {seed[1]}" if seed else "")
    return _Column(channel, unit_text, said_by)


def _cells(src: TextSource, line: int) -> list[str]:
    """The comma-separated cells of one line (the csv module only for a line with quotes: it is slower)."""
    text = src.lines[line - 1]
    if '"' not in text:
        return text.split(",")
    try:
        return next(csv.reader([text]))
    except csv.Error as exc:
        raise src.error(line, f"not a CSV row ({exc}); expected comma-separated cells") from None


def _header(src: TextSource) -> tuple[int, list[str], list[_Column]]:
    """The header row: its line, its cells as written and the parsed columns."""
    line = next((n for n, text in enumerate(src.lines, 1) if text.strip() and not is_comment(text)), None)
    if line is None:
        raise src.error(len(src.lines), f"no header row; expected {_EXPECTED}")
    cells = [c.strip() for c in _cells(src, line)]
    columns = [_column(src, line, i, cell) for i, cell in enumerate(cells)]
    taken = {c.channel for c in columns}
    for i, column in enumerate(columns):
        if column.channel == "seed_h":  # SEED horizontals: the first and second horizontal in column order
            channel = "h" if "h" not in taken else "h2"
            taken.add(channel)
            columns[i] = _Column(channel, column.unit_text, column.said_by)
    seen: dict[str, int] = {}
    for i, column in enumerate(columns):
        if column.channel in seen:
            raise src.error(
                line, f"columns {seen[column.channel] + 1} and {i + 1} are both the "
                f"{_CHANNEL_NAMES[column.channel]} channel; expected each channel once",
            )
        seen[column.channel] = i
    if "h" not in seen:
        raise src.error(line, f"no first horizontal acceleration column (acc or acc_h); {_COLUMN_HELP}")
    return line, cells, columns


def _file_unit(src: TextSource, line: int, columns: list[_Column], settings: Settings) -> tuple[str | None, str | None]:
    """The acceleration unit the file gives (canonical, as written), from the header or ``# units``."""
    named = {(parse_unit(c.unit_text), c.unit_text) for c in columns if c.channel != "t" and c.unit_text}
    if len({unit for unit, _ in named}) > 1:
        texts = ", ".join(sorted(text for _, text in named))
        raise src.error(line, f"the acceleration columns have different units ({texts}); expected one unit")
    if not named:
        return settings.unit, settings.unit_text
    unit, text = min(named)
    if settings.unit is not None and settings.unit != unit:
        raise src.error(
            settings.unit_line, f"units = {settings.unit_text} but the header (line {line}) says {text}; "
            "expected the same unit",
        )
    return unit, text


def read_csv(path: str | Path, *, dt: float | None = None, units: str | None = None) -> GroundMotion:
    """Read a CSV record (see the module docstring) into a `GroundMotion` [g, s].

    Args:
        path: the file.
        dt: time step [s] for a file without a time column or ``# dt`` setting (must agree if it has one).
        units: acceleration unit if neither the column names nor a ``# units`` setting give it.
    """
    path = Path(path)
    dt, units = given_dt(dt), given_unit(units)
    raw, sha = read_record(path)
    header_at = first_data_line(raw) if csv_ready(raw) else None
    if header_at is not None:  # the lines up to the header from the bytes; the rows are parsed from them too
        header_lines, body = byte_lines(raw, line_number(raw, header_at))
        src, n_lines = TextSource(path=path, lines=header_lines, sha256=sha), line_count(raw)
        settings = read_settings(src, comment_lines(raw))
    else:  # decoded and split into lines, which says what is wrong with the bytes if anything is
        src = source_from(path, raw, sha, _EXPECTED)
        n_lines, body = len(src.lines), 0
        settings = read_settings(src)
    header_line, cells, columns = _header(src)
    file_unit, unit_text = _file_unit(src, header_line, columns, settings)
    unit = agreed_unit(
        path, header_line, file_unit, units,
        "expected a unit in the column names (acc_g, acc [cm/s2]), a '# units = …' line or a given unit (--units)",
    )
    to_g = TO_G[unit]
    count = count_rows(raw, body) if header_at is not None else sum(
        1 for text in src.lines[header_line:] if text.strip() and not is_comment(text)
    )
    if count > MAX_SAMPLES:
        raise located(path, None, f"the record has {count:,} samples (data rows); expected at most {MAX_SAMPLES:,} "
                                  "(refused before parsing them)")
    parsed = None
    if header_at is not None and count and strict_rows(raw, body, len(cells)):
        parsed = parse_rows(raw, body, count, len(cells))
    channels: dict[str, np.ndarray] = {}
    for column, values in zip(columns, parsed or [], strict=False):
        if column.channel == "t":
            ok = math.isfinite(values.min()) and math.isfinite(values.max())  # NaN and inf, without a mask
        else:
            values *= to_g
            ok = bool(values.min() >= -MAX_ABS_G and values.max() <= MAX_ABS_G)  # NaN too
        if not ok:  # the exact check says which value
            channels = {}
            break
        channels[column.channel] = values
    del parsed
    lines: Sequence[int]
    if channels:
        lines = DataLines(raw, body, count)
        del raw
    else:
        if header_at is not None:
            src = source_from(path, raw, sha, _EXPECTED)
        del raw
        channels, lines = _exact_rows(src, header_line, cells, columns, unit)
    check_npts(src, settings, lines)
    if "t" in channels:
        column_dt, t0 = time_step(src, channels["t"], lines, settings)
        dt = matching_dt(path, lines[0], column_dt, dt)
        timing: dict[str, object] = {"dt_from": "time column", "t0": t0}
    else:
        dt = agreed_dt(
            path, header_line, settings.dt, dt,
            "a CSV file without a time column needs a '# dt = …' line or a given dt (--dt S)",
        )
        timing = {"dt_from": "given" if settings.dt is None else "file"}
    acc = {k: v for k, v in channels.items() if k != "t"}
    provenance = {
        "source": "file",
        "path": str(path.resolve()),
        "file": path.name,
        "format": "CSV",
        "columns": cells,
        **({"component": _component(path, header_line, columns)} if len(acc) == 1 else {}),
        "lines": n_lines,
        "units_in_file": unit_text or unit,
        "units_from": "given" if file_unit is None else "file",
        "to_g": TO_G[unit],
        "npts": len(lines),
        "dt": dt,
        **timing,
        "sha256": array_sha256(acc["h"]),
        "source_sha256": sha,
    }
    return GroundMotion(
        name=path.stem, dt=dt, acc_h=acc["h"], acc_h2=acc.get("h2"), acc_v=acc.get("v"), provenance=provenance
    )


def _component(path: Path, line: int, columns: list[_Column]) -> dict[str, object]:
    """The component of a one-channel CSV file: its column name, else its file name (`component.from_name`)."""
    column = next(c for c in columns if c.channel == "h")
    named = name_component(path)
    if column.said_by is None:
        return from_name(path, "the CSV column names no component (a bare 'acc')")
    if named is not None and named[0] != HORIZONTAL:
        raise located(path, line, f"{column.said_by} is a horizontal channel but {named[1]} says {named[0]}; "
                                  "expected the two to agree (rename the file or the column)")
    return component(HORIZONTAL, column.said_by, line)


def _exact_rows(
    src: TextSource, header_line: int, cells: list[str], columns: list[_Column], unit: str
) -> tuple[dict[str, np.ndarray], list[int]]:
    """The channels and the line of each row, row by row with the exact checks (`TextSource.number`,
    `.acceleration`): a file `source.parse_rows` does not take, which is either read the same or stopped at the
    first bad cell with its ``FILE:LINE`` error."""
    rows = _rows(src, header_line, len(cells))
    channels: dict[str, array[float]] = {c.channel: array("d") for c in columns}
    for line, row in rows:
        for index, (column, cell) in enumerate(zip(columns, row, strict=True)):
            what = f"column {index + 1} ({cells[index]})"
            if column.channel == "t":
                channels["t"].append(src.number(line, cell.strip(), what))
            else:
                channels[column.channel].append(src.acceleration(line, cell.strip(), what, TO_G[unit], unit))
    return {k: np.frombuffer(v, dtype=np.float64).copy() for k, v in channels.items()}, [line for line, _ in rows]


def _rows(src: TextSource, header_line: int, width: int) -> list[tuple[int, list[str]]]:
    """(line, cells) of every data row after the header; each with ``width`` cells."""
    rows: list[tuple[int, list[str]]] = []
    for line in range(header_line + 1, len(src.lines) + 1):
        text = src.lines[line - 1]
        if not text.strip() or is_comment(text):
            continue
        cells = _cells(src, line)
        if len(cells) != width:
            raise src.error(line, f"{len(cells)} cells; expected {width} like the header (line {header_line})")
        rows.append((line, cells))
    if not rows:
        raise src.error(len(src.lines), f"no data rows after the header (line {header_line}); expected {_EXPECTED}")
    return rows
