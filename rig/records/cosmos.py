"""Reader for COSMOS strong-motion files (format v01.20): V1 uncorrected and V2 corrected acceleration.

:func:`read_cosmos` walks a ``.V1``/``.V2``/``.V1C``/``.V2C`` file block by block by the counts its headers
announce (text lines, header values, comment lines, data values; header numbers 1-based as in the COSMOS tables),
reads the values from the fixed-width fields of each block's Fortran format and keeps the acceleration blocks
(velocity and displacement checked and skipped). Units: the data header's code (02 = g, 04 = cm/s², 10 = gal;
others refused), returned in g; dt is real-header value 62 [ms], returned in s. Channels by integer-header value
54: one channel → ``acc_h``; two horizontal (and a vertical) → ``acc_h``, ``acc_h2`` (``acc_v``); a ``Down``
channel is negated so that it reads positive up. The older CSMIP/DMG format is refused naming it. Every problem
raises `RecordError` naming the file, the line and what was expected.

The block layout, the fields, the channel codes and the memory it takes: docs/records.md §COSMOS files, block by
block.
"""

from __future__ import annotations

import math
import re
from array import array
from collections.abc import Callable, MutableSequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from .component import HORIZONTAL, UNKNOWN, VERTICAL, component, name_component, warn
from .motion import GroundMotion, array_sha256
from .source import (
    DT_RTOL,
    MAX_SAMPLES,
    ByteLines,
    TextSource,
    dt_problem,
    given_dt,
    located,
    matching_dt,
    matching_unit,
    plain_ascii,
    read_record,
    source_from,
)
from .units import TO_G, given_unit, parse_unit

_T = TypeVar("_T")

_EXPECTED = "a COSMOS strong-motion file: blocks of text, integer and real headers, comments and data"

#: 1-based numbers of the header values the reader uses.
INT_QUANTITY, INT_UNITS, INT_CHANNEL, INT_ORIENTATION = 2, 3, 50, 54
REAL_DT_MS = 62

#: COSMOS unit codes (Table 2) of acceleration the reader converts, with the canonical unit (`units.TO_G`).
ACCELERATION_CODES: dict[int, str] = {2: "g", 4: "cm/s/s", 10: "cm/s/s"}
_UNIT_NAMES: dict[int, str] = {
    1: "s", 2: "g", 3: "s and g", 4: "cm/s/s", 5: "cm/s", 6: "cm", 7: "in/s/s", 8: "in/s", 9: "in",
    10: "gal", 11: "mg", 12: "micro-g", 50: "counts", 51: "volts", 52: "millivolts",
}
_CODES_HELP = "02 (g), 04 (cm/s/s) or 10 (gal)"

#: COSMOS physical-parameter codes (Table 1) of integer-header value 2.
_QUANTITIES: dict[int, str] = {1: "acceleration", 2: "velocity", 3: "displacement"}

#: COSMOS orientation codes of integer-header value 54 (azimuths are 0-360).
_ORIENTATIONS: dict[int, str] = {
    400: "Up", 401: "Down", 402: "Vertical (sense not indicated)", 500: "Radial", 501: "Transverse",
    600: "Longitudinal", 601: "Tangential", 700: "H1 (azimuth unknown)", 701: "H2 (azimuth unknown)",
    2000: "Other (see comments)",
}
_VERTICAL_CODES = frozenset({400, 401, 402})
_HORIZONTAL_CODES = frozenset({500, 501, 600, 601, 700, 701})
_DOWN, _VERTICAL_UNSTATED = 401, 402

_DEFAULT_UNKNOWN = (-999, -999.0)
_MAX_FIELDS, _MAX_WIDTH = 1000, 1000

_TEXT_COUNT_RE = re.compile(r"\bwith\s+(?P<count>\d+)\s+text\s+lines?\b", re.I)
_UNKNOWN_RE = re.compile(r"unknown/unspecified\s*:(?P<values>.*)$", re.I)
_FOLLOW = r"header\s+values?\s+follows?\s+on\s+(?P<lines>\d+)\s+lines?\b"
_INT_HEADER_RE = re.compile(r"^\s*(?P<count>\d+)\s+Integer[- ]?" + _FOLLOW, re.I)
_REAL_HEADER_RE = re.compile(r"^\s*(?P<count>\d+)\s+Real[- ]?" + _FOLLOW, re.I)
_COMMENTS_RE = re.compile(r"^\s*(?P<count>\d+)\s+Comment\s+lines?\b", re.I)
_DATA_RE = re.compile(r"^\s*(?P<npts>\d+)\s+(?P<what>\S.*?)\s+(?:pts|points)\b", re.I)
_UNITS_RE = re.compile(r"\bunits\s*=\s*(?P<name>[^(,]*?)\s*(?:\(\s*(?P<code>\d+)\s*\))?\s*(?:,|$)", re.I)
_FORMAT_RE = re.compile(
    r"\bFormat\s*=\s*\(\s*(?P<count>\d*)\s*(?P<kind>ES|EN|[IFEDG])\s*(?P<width>\d+)(?:\.\d+)?\s*\)", re.I
)
_END_RE = re.compile(r"^\s*(?:/&)?[\s-]*End[- ]of[- ]data\b", re.I)
_DMG_RE = re.compile(r"^\s*(?:(?:UN)?CORRECTED\s+ACCELEROGRAM|RESPONSE\s+AND\s+FOURIER)\b", re.I)
_INTEGER_RE = re.compile(r"[-+]?\d+")

_INT_EXAMPLE = "' 100 Integer-header values follow on  10 lines, Format= (10I8)'"
_REAL_EXAMPLE = "' 100 Real-header values follow on  20 lines, Format= (5F15.6)'"
_COMMENTS_EXAMPLE = "'   2 Comment line(s) follow, each starting with a \"|\":'"
_DATA_EXAMPLE = "'   42000 acceleration pts, approx  210 secs, units=cm/sec2(04),Format=(1E15.6)'"


# --------------------------------------------------------------------------------------------------
# Lines, Fortran formats and fixed-width fields
# --------------------------------------------------------------------------------------------------


def _shown(text: str) -> str:
    """A line quoted in an error message (stripped, at most 70 characters)."""
    text = text.strip()
    return repr(text if len(text) <= 70 else text[:67] + "...")


def _line(src: TextSource, lineno: int, expected: str) -> str:
    """Line ``lineno`` (1-based); a truncated-file error saying what was ``expected`` there if it is missing."""
    if lineno > len(src.lines):
        raise src.error(
            len(src.lines), f"truncated file: it ends at line {len(src.lines)}; expected {expected} on line {lineno}"
        )
    return src.lines[lineno - 1]


@dataclass(frozen=True)
class FortranFormat:
    """A Fortran edit descriptor such as ``8F10.5``: ``count`` fields a line, each ``width`` characters."""

    count: int
    kind: str
    width: int
    text: str

    @property
    def integer(self) -> bool:
        """True for ``I`` (integer) fields."""
        return self.kind == "I"


def _format(src: TextSource, lineno: int, text: str, integer: bool) -> FortranFormat:
    """The ``Format=(…)`` of an announcement line: integer (``I``) or real (``F``, ``E``, ``D``, ``G``) fields."""
    example = "(10I8)" if integer else "(8F10.5) or (1E15.6)"
    match = _FORMAT_RE.search(text)
    if match is None:
        raise src.error(lineno, f"no Fortran format; expected 'Format=(…)' such as {example}, got {_shown(text)}")
    kind = match["kind"].upper()
    count, width = int(match["count"] or "1"), int(match["width"])
    spec = match.group(0)[match.group(0).index("(") + 1 : -1].strip()
    if integer and kind != "I":
        raise src.error(lineno, f"Format=({spec}) does not hold integers; expected a format such as {example}")
    if not (1 <= count <= _MAX_FIELDS and 1 <= width <= _MAX_WIDTH):
        raise src.error(
            lineno,
            f"Format=({spec}) is not a usable layout; expected 1-{_MAX_FIELDS} fields of 1-{_MAX_WIDTH} characters",
        )
    return FortranFormat(count=count, kind=kind, width=width, text=spec)


def _lines_for(values: int, fmt: FortranFormat) -> int:
    """Number of lines ``values`` fields take in format ``fmt`` (the last line may be short)."""
    return -(-values // fmt.count)


def _fields(src: TextSource, lineno: int, fmt: FortranFormat, expected: int, of_what: str) -> list[tuple[str, str]]:
    """The ``expected`` fixed-width fields of a line as (token, description); errors name the columns."""
    text = src.lines[lineno - 1].rstrip()
    width = fmt.width
    present = -(-len(text) // width)
    if present != expected:
        raise src.error(
            lineno,
            f"{present} field(s) of {width} characters on the line; expected {expected} ({of_what}, "
            f"Format=({fmt.text}))",
        )
    fields: list[tuple[str, str]] = []
    for index in range(expected):
        first = index * width
        field = text[first : first + width]
        where = f"field {index + 1} (columns {first + 1}-{first + width})"
        if len(field) < width:
            raise src.error(lineno, f"{where} is cut short at column {len(text)}; expected {width} characters")
        if not field.strip():
            raise src.error(lineno, f"{where} is blank; expected a number ({of_what})")
        fields.append((field.strip(), where))
    return fields


def _integer(src: TextSource, lineno: int, token: str, where: str) -> int:
    """An integer field (``I`` format)."""
    if not _INTEGER_RE.fullmatch(token):
        raise src.error(lineno, f"{where}, {token!r}, is not an integer; expected digits such as -999")
    return int(token)


def _decimal_point(src: TextSource, lineno: int, token: str, where: str, fmt: FortranFormat) -> None:
    """A number in a real (``F``, ``E``, …) field must carry its decimal point: Fortran would imply one."""
    if not fmt.integer and "." not in token:
        raise src.error(
            lineno, f"{where}, {token!r}, has no decimal point; expected a number as Format=({fmt.text}) writes it"
        )


def _real(src: TextSource, lineno: int, token: str, where: str, fmt: FortranFormat) -> float:
    """A real field: a finite decimal number, with a decimal point unless the format is ``I``."""
    value = src.number(lineno, token, where)
    _decimal_point(src, lineno, token, where, fmt)
    return value


def _acceleration(
    src: TextSource, lineno: int, token: str, where: str, fmt: FortranFormat, to_g: float, unit: str
) -> float:
    """An acceleration field converted to g (``to_g``) and checked plausible (`TextSource.acceleration`)."""
    value = src.acceleration(lineno, token, where, to_g, unit)
    _decimal_point(src, lineno, token, where, fmt)
    return value


def _values(
    src: TextSource,
    first: int,
    count: int,
    fmt: FortranFormat,
    of_what: str,
    parse: Callable[[int, str, str], _T],
    values: MutableSequence[_T],
) -> MutableSequence[_T]:
    """``count`` values laid out by ``fmt`` from line ``first`` on, each parsed by ``parse(line, token, where)``, added
    to ``values`` (an ``array("d")`` for data: 8 bytes a value, no Python float kept)."""
    lines = _lines_for(count, fmt)
    for offset in range(lines):
        lineno = first + offset
        expected = min(fmt.count, count - len(values))
        which = f"value {len(values) + 1}" if expected == 1 else f"values {len(values) + 1}-{len(values) + expected}"
        text = _line(src, lineno, f"{which} of {of_what}")
        if _END_RE.match(text):
            raise src.error(
                lineno,
                f"truncated data: 'End-of-data' after {len(values)} values; expected {count} values "
                f"({of_what}, {lines} lines of Format=({fmt.text}))",
            )
        values.extend(parse(lineno, token, where) for token, where in _fields(src, lineno, fmt, expected, of_what))
    return values


# --------------------------------------------------------------------------------------------------
# One block: text header, integer header, real header, comments, data header, data, End-of-data
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Header:
    """The values of an integer or real header and where they are."""

    values: list[Any]
    line: int
    fmt: FortranFormat

    def line_of(self, number: int) -> int:
        """The line holding value ``number`` (1-based)."""
        return self.line + 1 + (number - 1) // self.fmt.count


@dataclass(frozen=True)
class _Block:
    """One block of a COSMOS file (one channel, one quantity).

    Attributes:
        line: its first line (the text header's line 1); ``title`` that line's text.
        quantity: "acceleration", "velocity", "displacement" or what the data header says.
        npts: number of values; ``data_line`` the data header's line; ``fmt`` the values' format.
        ints, reals: the integer and real headers; ``unknown_int``/``unknown_real`` the file's markers.
        values: the acceleration [g] (acceleration blocks only, else None); ``end`` the End-of-data line.
        unit_text, unit_code: the unit as the data header writes it and its COSMOS code (None if absent).
    """

    line: int
    title: str
    quantity: str
    npts: int
    data_line: int
    fmt: FortranFormat
    ints: _Header
    reals: _Header
    unknown_int: int
    unknown_real: float
    unit_text: str
    unit_code: int | None
    values: array[float] | None
    end: int


def _text_header(src: TextSource, start: int) -> tuple[int, int, float]:
    """Number of text-header lines (from line 1) and the file's unknown-value markers (int, real)."""
    first = src.lines[start - 1]
    match = _TEXT_COUNT_RE.search(first)
    if match is None and _DMG_RE.match(first):
        raise src.error(
            start,
            f"this is a CSMIP/DMG-format file ({_shown(first)}), not COSMOS v01.20; expected a COSMOS file: download "
            "the same record's COSMOS files (.V1C/.V2C) from CESMD (strongmotioncenter.org), which hold the same "
            "channels",
        )
    if match is None or int(match["count"]) == 0:
        raise src.error(
            start,
            "expected the first line of a COSMOS block, e.g. 'Corrected acceleration    (Format v01.20 with 13 "
            f"text lines)', got {_shown(first)}",
        )
    count = int(match["count"])
    _line(src, start + count - 1, f"line {count} of the {count}-line text header announced on line {start}")
    unknown = _DEFAULT_UNKNOWN
    for lineno in range(start + 1, start + count):
        marker = _UNKNOWN_RE.search(src.lines[lineno - 1])
        if marker is not None:
            unknown = _unknown_markers(src, lineno, marker["values"])
    return count, *unknown


def _unknown_markers(src: TextSource, lineno: int, text: str) -> tuple[int, float]:
    """The integer and real values the file uses for unknown, e.g. from ``-999, -999.00``."""
    tokens = [t for t in re.split(r"[\s,]+", text) if t]
    if len(tokens) != 2 or not _INTEGER_RE.fullmatch(tokens[0]):
        raise src.error(lineno, f"expected the unknown-value markers as '<integer>, <real>' such as '-999, -999.0', "
                                f"got {_shown(text)}")
    return int(tokens[0]), src.number(lineno, tokens[1], "the real unknown-value marker")


def _header(src: TextSource, lineno: int, pattern: re.Pattern[str], example: str, integer: bool) -> _Header:
    """The integer or real header announced on line ``lineno``: count and lines must agree with the format."""
    label = "integer header" if integer else "real header"
    text = _line(src, lineno, f"the {label} line {example}")
    match = pattern.match(text)
    if match is None:
        raise src.error(lineno, f"expected the {label} line {example}, got {_shown(text)}")
    count, lines = int(match["count"]), int(match["lines"])
    fmt = _format(src, lineno, text, integer)
    if count == 0 or _lines_for(count, fmt) != lines:
        raise src.error(
            lineno,
            f"{count} {label} values on {lines} lines do not fit Format=({fmt.text}), which puts "
            f"{fmt.count} a line; expected {_lines_for(count, fmt) or 'at least 1'} lines",
        )
    of_what = f"the {label} announced on line {lineno}"
    if integer:
        values: list[Any] = list(
            _values(src, lineno + 1, count, fmt, of_what, lambda n, t, w: _integer(src, n, t, w), [])
        )
    else:
        values = list(_values(src, lineno + 1, count, fmt, of_what, lambda n, t, w: _real(src, n, t, w, fmt), []))
    return _Header(values=values, line=lineno, fmt=fmt)


def _require(src: TextSource, header: _Header, number: int, label: str, meaning: str) -> None:
    """Header ``header`` must hold value ``number`` (1-based)."""
    if len(header.values) < number:
        raise src.error(
            header.line,
            f"the {label} holds {len(header.values)} values; expected at least {number} (value {number}: {meaning})",
        )


def _comments(src: TextSource, lineno: int) -> int:
    """The line after the comment lines announced on line ``lineno`` (each must start with '|')."""
    text = _line(src, lineno, f"the comment line {_COMMENTS_EXAMPLE}")
    match = _COMMENTS_RE.match(text)
    if match is None:
        raise src.error(lineno, f"expected the comment line {_COMMENTS_EXAMPLE}, got {_shown(text)}")
    count = int(match["count"])
    for index in range(1, count + 1):
        comment = _line(src, lineno + index, f"comment {index} of {count} announced on line {lineno}")
        if not comment.lstrip().startswith("|"):
            raise src.error(
                lineno + index,
                f"expected comment {index} of the {count} announced on line {lineno}, starting with '|', "
                f"got {_shown(comment)}",
            )
    return lineno + count + 1


def _quantity(what: str) -> str:
    """The quantity a data header names: ``acceleration`` (also ``uncor. accel.``), ``velocity``, ``displacement``."""
    lowered = what.lower()
    for stem, quantity in (("acc", "acceleration"), ("vel", "velocity"), ("dis", "displacement")):
        if stem in lowered:
            return quantity
    return what.strip()


def _check_quantity(src: TextSource, lineno: int, quantity: str, ints: _Header, unknown: int) -> None:
    """The data header's quantity must agree with integer-header value 2 (when that is known)."""
    code = ints.values[INT_QUANTITY - 1]
    if code == unknown:
        return
    in_header = _QUANTITIES.get(code, f"code {code}")
    if in_header != quantity:
        raise src.error(
            lineno,
            f"the data header says {quantity} but integer-header value {INT_QUANTITY} (line "
            f"{ints.line_of(INT_QUANTITY)}) is {code} ({in_header}); expected the same quantity",
        )


def _unit_code(src: TextSource, lineno: int, text: str, ints: _Header, unknown: int) -> tuple[str, int | None]:
    """The unit name and COSMOS code of a data header; the code must agree with integer-header value 3."""
    match = _UNITS_RE.search(text)
    name = match["name"].strip() if match else ""
    code = int(match["code"]) if match and match["code"] else None
    in_header = ints.values[INT_UNITS - 1]
    if code is not None and in_header not in (unknown, code):
        raise src.error(
            lineno,
            f"the data header gives unit code {code:02d} but integer-header value {INT_UNITS} (line "
            f"{ints.line_of(INT_UNITS)}) is {in_header}; expected the same unit code",
        )
    if code is None and in_header != unknown:
        code = in_header
    return name, code


def _block(src: TextSource, start: int) -> _Block:
    """The block whose text header starts at line ``start``."""
    count, unknown_int, unknown_real = _text_header(src, start)
    ints = _header(src, start + count, _INT_HEADER_RE, _INT_EXAMPLE, integer=True)
    _require(src, ints, INT_ORIENTATION, "integer header", "the sensor orientation")
    reals_line = ints.line + _lines_for(len(ints.values), ints.fmt) + 1
    reals = _header(src, reals_line, _REAL_HEADER_RE, _REAL_EXAMPLE, integer=False)
    _require(src, reals, REAL_DT_MS, "real header", "the sampling interval [ms]")
    data_line = _comments(src, reals.line + _lines_for(len(reals.values), reals.fmt) + 1)
    text = _line(src, data_line, f"the data header {_DATA_EXAMPLE}")
    match = _DATA_RE.match(text)
    if match is None:
        raise src.error(data_line, f"expected the data header {_DATA_EXAMPLE}, got {_shown(text)}")
    npts, quantity = int(match["npts"]), _quantity(match["what"])
    if npts == 0:
        raise src.error(data_line, f"the data header announces 0 values; expected {quantity} values")
    if npts > MAX_SAMPLES:
        raise src.error(data_line, f"the data header announces {npts:,} values; expected at most {MAX_SAMPLES:,} "
                                   "(refused before parsing them)")
    fmt = _format(src, data_line, text, integer=False)
    _check_quantity(src, data_line, quantity, ints, unknown_int)
    unit_text, unit_code = _unit_code(src, data_line, text, ints, unknown_int)
    block = _Block(
        line=start, title=src.lines[start - 1].strip(), quantity=quantity, npts=npts, data_line=data_line,
        fmt=fmt, ints=ints, reals=reals, unknown_int=unknown_int, unknown_real=unknown_real,
        unit_text=unit_text, unit_code=unit_code, values=None, end=0,
    )
    return _with_data(src, block)


def _with_data(src: TextSource, block: _Block) -> _Block:
    """The block with its values read (acceleration: in g, checked plausible) and its End-of-data line."""
    of_what = f"the {block.npts} {block.quantity} values announced on line {block.data_line}"
    fmt = block.fmt
    if block.quantity == "acceleration":
        unit = _acceleration_unit(src, block)
        shown = block.unit_text or unit
        values: array[float] | None = array("d")
        assert values is not None
        _values(
            src, block.data_line + 1, block.npts, fmt, of_what,
            lambda n, t, w: _acceleration(src, n, t, w, fmt, TO_G[unit], shown), values,
        )
    else:
        _values(
            src, block.data_line + 1, block.npts, fmt, of_what, lambda n, t, w: _real(src, n, t, w, fmt), array("d")
        )
        values = None
    end = block.data_line + 1 + _lines_for(block.npts, fmt)
    text = _line(src, end, f"'End-of-data for Chan …' after {of_what}")
    if not _END_RE.match(text):
        raise src.error(
            end,
            f"extra data or a missing end line: {of_what} take {_lines_for(block.npts, fmt)} lines of "
            f"Format=({fmt.text}), but line {end} is {_shown(text)}; expected 'End-of-data for Chan …'",
        )
    return replace(block, values=values, end=end)


def _acceleration_unit(src: TextSource, block: _Block) -> str:
    """The canonical unit of an acceleration block, from its COSMOS unit code (or, without one, its name)."""
    code = block.unit_code
    if code is None:
        unit = parse_unit(block.unit_text) if block.unit_text else None
        if unit is None:
            raise src.error(
                block.data_line,
                f"no unit code: expected 'units=<name>(<code>)' with code {_CODES_HELP} in the data header "
                f"or integer-header value {INT_UNITS}",
            )
        return unit
    if code not in ACCELERATION_CODES:
        meaning = _UNIT_NAMES.get(code, "not a COSMOS unit code")
        raise src.error(
            block.data_line,
            f"unit code {code:02d} ({meaning}) is not a supported acceleration unit; expected {_CODES_HELP}",
        )
    return ACCELERATION_CODES[code]


def _blocks(src: TextSource) -> list[_Block]:
    """Every block of the file, in order (blank lines between blocks and at the end are allowed)."""
    blocks: list[_Block] = []
    lineno = 1
    while lineno <= len(src.lines):
        if not src.lines[lineno - 1].strip():
            lineno += 1
            continue
        block = _block(src, lineno)
        blocks.append(block)
        lineno = block.end + 1
    return blocks


# --------------------------------------------------------------------------------------------------
# Channels: dt, orientation and their roles in the record
# --------------------------------------------------------------------------------------------------


def _dt(src: TextSource, block: _Block) -> float:
    """The block's sampling interval [s] from real-header value 62 [ms]."""
    value = block.reals.values[REAL_DT_MS - 1]
    line = block.reals.line_of(REAL_DT_MS)
    label = f"the sampling interval (real-header value {REAL_DT_MS})"
    if value == block.unknown_real:
        raise src.error(line, f"{label} is unknown ({value:g}); expected the interval in milliseconds, e.g. 10.0")
    problem = dt_problem(value / 1000.0)
    if problem:
        raise src.error(line, f"{label}, {value:g} ms, {problem} (given in ms, e.g. 10.0)")
    return value / 1000.0


def _orientation(code: int, unknown: int) -> tuple[str, str]:
    """Kind ("horizontal", "vertical" or "other") and description of an orientation (integer value 54)."""
    if code == unknown:
        return "other", "unknown"
    if code == 0:
        return "other", "0 (not a COSMOS azimuth, which runs 1-360 with north = 360)"
    if 1 <= code <= 360:
        return "horizontal", f"{code} deg"
    if code in _VERTICAL_CODES:
        return "vertical", _ORIENTATIONS[code]
    if code in _HORIZONTAL_CODES:
        return "horizontal", _ORIENTATIONS[code]
    return "other", _ORIENTATIONS.get(code, f"code {code} (not a COSMOS orientation)")


@dataclass(frozen=True)
class _Channel:
    """An acceleration block read as a channel: acceleration [g] (positive up if vertical), dt [s]."""

    block: _Block
    acc: np.ndarray
    dt: float
    kind: str
    orientation: str
    unit: str

    def describe(self) -> str:
        """E.g. ``chan 2 (line 190): Up``."""
        return f"chan {self.number} (line {self.block.line}): {self.orientation}"

    @property
    def number(self) -> int | str:
        """The station channel number (integer-header value 50), or "?" if unknown."""
        value = self.block.ints.values[INT_CHANNEL - 1]
        return "?" if value == self.block.unknown_int else value

    def provenance(self) -> dict[str, Any]:
        """JSON view of the channel."""
        code = self.block.ints.values[INT_ORIENTATION - 1]
        return {
            "line": self.block.line,
            "title": self.block.title,
            "channel": self.number if isinstance(self.number, int) else None,
            "orientation": self.orientation,
            "orientation_code": code,
            "negated_to_up": code == _DOWN,
            "units_in_file": self.block.unit_text or self.unit,
            "unit_code": self.block.unit_code,
            "to_g": TO_G[self.unit],
            "format": self.block.fmt.text,
            "npts": self.block.npts,
            "dt": self.dt,
        }


def _channel(src: TextSource, block: _Block, given: float | None, units: str | None) -> _Channel:
    """An acceleration block as a channel, its dt and unit checked against the given ones."""
    dt = matching_dt(src.path, block.reals.line_of(REAL_DT_MS), _dt(src, block), given)
    unit = matching_unit(src.path, block.data_line, _acceleration_unit(src, block), units)
    code = block.ints.values[INT_ORIENTATION - 1]
    kind, orientation = _orientation(code, block.unknown_int)
    acc = np.asarray(block.values, dtype=np.float64)
    if code == _DOWN:
        acc = 0.0 - acc
        orientation += " (negated to up)"
    elif code == _VERTICAL_UNSTATED:
        orientation += ", taken as up"
    return _Channel(block=block, acc=acc, dt=dt, kind=kind, orientation=orientation, unit=unit)


def _roles(src: TextSource, channels: list[_Channel]) -> dict[str, _Channel]:
    """Which channel is acc_h, acc_h2, acc_v: one channel, or two horizontal and at most one vertical."""
    if len(channels) == 1:
        return {"h": channels[0]}
    horizontal = [c for c in channels if c.kind == "horizontal"]
    vertical = [c for c in channels if c.kind == "vertical"]
    if len(horizontal) != 2 or len(vertical) > 1 or len(channels) != len(horizontal) + len(vertical):
        found = "; ".join(c.describe() for c in channels)
        raise located(
            src.path,
            None,
            f"{len(channels)} acceleration channels ({found}); expected one channel, or two horizontal and at "
            f"most one vertical (orientation = integer-header value {INT_ORIENTATION})",
        )
    roles = {"h": horizontal[0], "h2": horizontal[1]} | ({"v": vertical[0]} if vertical else {})
    _check_same_grid(src, roles["h"], [c for role, c in roles.items() if role != "h"])
    return roles


def _component(src: TextSource, channel: _Channel, named: tuple[str, str] | None) -> dict[str, Any]:
    """The provenance entry ``component`` (`component`) of a one-channel file: its orientation code, or for an
    unknown one the file name's SEED channel or ``-UP`` (`component.name_component`); the two must agree."""
    kind = {"horizontal": HORIZONTAL, "vertical": VERTICAL}.get(channel.kind, UNKNOWN)
    code = channel.block.ints.values[INT_ORIENTATION - 1]
    said_by = f"COSMOS orientation code {code}: {channel.orientation}, chan {channel.number}"
    line = channel.block.ints.line_of(INT_ORIENTATION)
    if named is not None and kind == UNKNOWN:
        return component(named[0], named[1])
    if named is not None and named[0] != kind:
        raise src.error(line, f"the {said_by} is {kind} but {named[1]} says {named[0]}; expected the two to agree "
                              "(rename the file)")
    return component(kind, said_by, line)


def _check_same_grid(src: TextSource, first: _Channel, others: list[_Channel]) -> None:
    """The channels of one record share dt (`DT_RTOL`) and the number of samples."""
    for other in others:
        if not math.isclose(other.dt, first.dt, rel_tol=DT_RTOL):
            raise src.error(
                other.block.reals.line_of(REAL_DT_MS),
                f"chan {other.number} has dt = {other.dt:g} s but chan {first.number} (line "
                f"{first.block.reals.line_of(REAL_DT_MS)}) has dt = {first.dt:g} s; expected the channels of one "
                "record to share dt",
            )
        if other.block.npts != first.block.npts:
            raise src.error(
                other.block.data_line,
                f"chan {other.number} has {other.block.npts} samples but chan {first.number} (line "
                f"{first.block.data_line}) has {first.block.npts}; expected the same number of samples in every "
                "channel",
            )


def read_cosmos(path: str | Path, *, dt: float | None = None, units: str | None = None) -> GroundMotion:
    """Read a COSMOS V1/V2 file (see the module docstring) into a `GroundMotion` [g, s].

    Args:
        path: the file (``.V1``, ``.V2``, ``.V1C``, ``.V2C``).
        dt: time step [s]; if given it must agree with the file's (real-header value 62, in ms).
        units: acceleration unit; if given it must agree with the file's unit code (``g``, ``cm/s/s``).

    The motion's name is the file stem; ``provenance`` holds the path, format, line count, every block
    (line, quantity, kept or skipped), the channels used (orientation, unit, npts, dt), npts, dt,
    ``sha256`` of the float64 ``acc_h`` values [g] and ``source_sha256`` of the file's bytes.
    """
    path = Path(path)
    given, units = given_dt(dt), given_unit(units)
    raw, sha = read_record(path)
    if plain_ascii(raw):  # lines decoded from the bytes one at a time, not a list of strings (a long record)
        src = TextSource(path=path, lines=ByteLines(raw), sha256=sha)
    else:  # decoded and split into lines, which says what is wrong with the bytes if anything is
        src = source_from(path, raw, sha, _EXPECTED)
    del raw
    blocks = _blocks(src)
    accelerations = [b for b in blocks if b.quantity == "acceleration"]
    if not accelerations:
        found = ", ".join(f"{b.quantity} (line {b.line})" for b in blocks)
        raise src.error(blocks[0].line, f"no acceleration block (found {found}); expected at least one "
                                        "acceleration block (a V1 or V2 acceleration file)")
    channels = [_channel(src, b, given, units) for b in accelerations]
    n_lines, src = len(src.lines), TextSource(path=path, lines=[], sha256=src.sha256)  # the file's bytes let go
    named = name_component(path) if len(channels) == 1 else None
    for channel in channels:
        if channel.kind == "other" and named is None:
            warn(
                f"{path}:{channel.block.ints.line_of(INT_ORIENTATION)}: chan {channel.number} has orientation "
                f"{channel.orientation} (integer-header value {INT_ORIENTATION}); its direction is unknown, check it "
                "before playing it"
            )
    roles = _roles(src, channels)
    first = roles["h"]
    provenance = {
        "source": "file",
        "path": str(path.resolve()),
        "file": path.name,
        "format": "COSMOS v01.20",
        "title": first.block.title,
        "lines": n_lines,
        "blocks": [
            {"line": b.line, "quantity": b.quantity, "npts": b.npts, "kept": b.quantity == "acceleration"}
            for b in blocks
        ],
        "channels": {role: channel.provenance() for role, channel in roles.items()},
        **({"component": _component(src, first, named)} if len(roles) == 1 else {}),
        "npts": first.block.npts,
        "dt": first.dt,
        "sha256": array_sha256(first.acc),
        "source_sha256": src.sha256,
    }
    return GroundMotion(
        name=path.stem,
        dt=first.dt,
        acc_h=first.acc,
        acc_h2=roles["h2"].acc if "h2" in roles else None,
        acc_v=roles["v"].acc if "v" in roles else None,
        provenance=provenance,
    )

