"""A record file read as text: its bytes' checksum, its lines, strict numbers and located errors.

Every text reader (``.AT2``, plain text, CSV) starts here, so that all of them agree on what a readable
file is: UTF-8 (an initial byte-order mark is dropped; ASCII is UTF-8), no NUL bytes, lines ended by LF,
CRLF, CR or CR CR LF (one line break, as a text editor shows it). Each problem becomes a `RecordError` whose
message starts with ``file:line:`` and says what was expected.
"""

from __future__ import annotations

import bisect
import hashlib
import math
import re
from array import array
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import overload

import numpy as np

from analysis.input_file import MIB, InputFileError, read_regular_file

from .motion import RecordError

#: Largest record file read [bytes]: 64 MiB holds 10 minutes of three channels at 1 kHz several times over.
MAX_FILE_BYTES = 64 * MIB

#: Most samples a text record may hold [samples]: 2^22 = 4,194,304, 70 minutes at 1 kHz (and 32 MiB of float64 per
#: channel); counted from the data lines before a number is parsed.
MAX_SAMPLES = 1 << 22

#: Longest line of a text record [characters]: record lines are tens of characters; the bound keeps every
#: per-line pattern linear in the file's size.
MAX_LINE_CHARS = 1000

#: Time steps [s] a record may have: 10 µs (100 kHz) to 1 s; outside, the file or the given dt is wrong.
DT_MIN_S, DT_MAX_S = 1e-5, 1.0

#: Longest record [s] (npts · dt): 20 minutes, beyond the longest strong-motion recordings (about 10 min).
MAX_DURATION_S = 1200.0

#: Largest acceleration magnitude a reader accepts [g]: beyond it the unit is wrong or the file is damaged.
MAX_ABS_G = 100.0

#: Relative tolerance within which two time steps [s] (file and user, or two components) agree.
DT_RTOL = 1e-6

_NUMBER_RE = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][-+]?\d+)?")
_NONFINITE_RE = re.compile(r"[-+]?(?:nan|inf|infinity)", re.I)
#: A line break: LF, CR LF, CR, or CR CR LF (written by some archives' double conversion), counted as one
#: line as a text editor shows it.
_LINE_BREAK_RE = re.compile(r"\r*\n|\r")
_BOM = b"\xef\xbb\xbf"
#: The first line longer than `MAX_LINE_CHARS` (in text whose line breaks are LF).
_LONG_LINE_RE = re.compile(rf"[^\n]{{{MAX_LINE_CHARS + 1},}}")

# The same checks on a file's bytes, for the readers that parse a clean file without decoding it (`plain_ascii`).
_LINE_BREAK_BYTES_RE = re.compile(rb"\r*\n|\r")
#: A line longer than `MAX_LINE_CHARS`, tried only where a line starts (linear in the file's size, not its lines').
_LONG_LINE_BYTES_RE = re.compile(rb"(?:\A|(?<=[\r\n]))[^\r\n]{%d}" % (MAX_LINE_CHARS + 1))
_NONBLANK_BYTES_RE = re.compile(rb"\S")
_SPACE_BYTES_RE = re.compile(rb"\s")
_TOKEN_BYTES_RE = re.compile(rb"\S+")
#: A whitespace-separated token that is not a strict decimal number without a Fortran ``D`` exponent (such a file
#: is read line by line, by `TextSource.number`, which says what is wrong or reads the ``D``).
_BAD_TOKEN_BYTES_RE = re.compile(rb"(?<!\S)(?![-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?!\S))\S")
#: Bytes of a file parsed by numpy at a time (`parse_numbers`): a copy this long is all the parsing adds.
CHUNK_BYTES = 1 << 16


def located(path: Path, line: int | None, message: str) -> RecordError:
    """A `RecordError` that starts with ``file:line:`` (or ``file:`` when no line applies)."""
    where = f"{path}:{line}" if line is not None else f"{path}"
    return RecordError(f"{where}: {message}")


def _line_and_column(raw: bytes, offset: int) -> tuple[int, int]:
    """1-based line and column of a byte offset (lines as `TextSource.lines` counts them)."""
    head = re.sub(rb"\r*\n|\r", b"\n", raw[:offset])
    return head.count(b"\n") + 1, len(head) - (head.rfind(b"\n") + 1) + 1


@dataclass(frozen=True)
class TextSource:
    """The decoded lines of a record file and the SHA-256 of its bytes.

    Attributes:
        path: the file as given.
        lines: text of each line without its line break; ``lines[0]`` is line 1.
        sha256: hex SHA-256 of the file's bytes as stored (before decoding).
    """

    path: Path
    lines: Sequence[str]
    sha256: str

    def error(self, line: int | None, message: str) -> RecordError:
        """A `RecordError` located at ``line`` of this file."""
        return located(self.path, line, message)

    def number(self, line: int, token: str, what: str) -> float:
        """A strict decimal number (Fortran ``D`` exponents allowed), finite as a 64-bit float."""
        if _NONFINITE_RE.fullmatch(token):
            raise self.error(line, f"{what} is {token!r}; expected a finite number")
        if not _NUMBER_RE.fullmatch(token):
            raise self.error(line, f"{what}, {token!r}, is not a number; expected a decimal number such as -1.25E-02")
        value = float(token.replace("d", "e").replace("D", "e"))
        if math.isinf(value):
            raise self.error(line, f"{what}, {token!r}, overflows a 64-bit float; expected |value| < 1.8E+308")
        return value

    def acceleration(self, line: int, token: str, what: str, to_g: float, unit: str) -> float:
        """A number in the file's unit, converted to g and checked against `MAX_ABS_G`."""
        value = self.number(line, token, what) * to_g
        if abs(value) > MAX_ABS_G:
            raise self.error(
                line,
                f"{what}, {token!r} {unit} = {value:.4g} g, is not a plausible ground acceleration; "
                f"expected |acceleration| <= {MAX_ABS_G:g} g (is the unit right?)",
            )
        return value

    def check_dt(self, line: int, dt: float, text: str, label: str = "dt") -> float:
        """``dt`` [s] as read from ``text``: within [`DT_MIN_S`, `DT_MAX_S`], else an error located at ``line``."""
        problem = dt_problem(dt)
        if problem:
            raise self.error(line, f"{label} = {text!r} {problem}")
        return dt


def dt_problem(dt: float) -> str | None:
    """What is wrong with a record's time step [s] (outside [`DT_MIN_S`, `DT_MAX_S`]), or None."""
    if math.isfinite(dt) and DT_MIN_S <= dt <= DT_MAX_S:
        return None
    return f"is not a record's time step; expected {DT_MIN_S:g} s to {DT_MAX_S:g} s, such as 0.01 s"


def read_record_bytes(path: Path, expected: str) -> bytes:
    """The bytes of a record file: a regular file of at most `MAX_FILE_BYTES` (FIFOs, devices refused)."""
    try:
        return read_regular_file(path, MAX_FILE_BYTES, expected)
    except InputFileError as exc:
        raise located(path, None, str(exc)) from None


def _decoded(path: Path, raw: bytes, expected: str) -> str:
    """The text of a record file's bytes (BOM dropped, line breaks as LF) after the checks every reader shares:
    not empty, no NUL byte, UTF-8, no line longer than `MAX_LINE_CHARS`."""
    body = raw.removeprefix(_BOM)
    if not body.strip():
        raise located(path, 1, f"the file is empty; expected {expected}")
    nul = body.find(b"\x00")
    if nul >= 0:
        line, col = _line_and_column(body, nul)
        raise located(path, line, f"NUL byte at column {col}; expected a text file (this looks like a binary file)")
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as exc:
        line, col = _line_and_column(body, exc.start)
        raise located(
            path, line, f"byte 0x{body[exc.start]:02x} at column {col} is not UTF-8 text; expected a UTF-8 text file"
        ) from None
    del body
    if "\r" in text:
        text = _LINE_BREAK_RE.sub("\n", text)
    longest = max(_LONG_LINE_RE.finditer(text), key=lambda m: m.end() - m.start(), default=None)
    if longest is not None:  # the match is the whole line: it starts where a line starts
        line, length = text.count("\n", 0, longest.start()) + 1, longest.end() - longest.start()
        raise located(
            path, line, f"the line is {length:,} characters long; expected lines of at most "
            f"{MAX_LINE_CHARS} characters ({expected})",
        )
    return text


def read_record(path: Path) -> tuple[bytes, str]:
    """The bytes of a record file (`read_record_bytes`) and their hex SHA-256."""
    raw = read_record_bytes(path, "a record file")
    return raw, hashlib.sha256(raw).hexdigest()


def plain_ascii(raw: bytes) -> bool:
    """True if ``raw`` passes every check of a readable file (see `read_source`) as it is: ASCII (so UTF-8, with no
    byte-order mark), no NUL byte, not blank, no line longer than `MAX_LINE_CHARS`. Such a file can be parsed from its
    bytes (`byte_lines`, `parse_numbers`) without decoding it into a copy; any other goes through `source_from`,
    which says what is wrong with it."""
    return (
        raw.isascii() and b"\x00" not in raw and _NONBLANK_BYTES_RE.search(raw) is not None
        and _LONG_LINE_BYTES_RE.search(raw) is None
    )


def line_start(raw: bytes, skip: int) -> int:
    """The offset in ``raw`` where the line after its first ``skip`` lines starts (``len(raw)`` if it has fewer),
    with the line breaks `read_source` knows."""
    if skip <= 0:
        return 0
    for k, match in enumerate(_LINE_BREAK_BYTES_RE.finditer(raw), start=1):
        if k == skip:
            return match.end()
    return len(raw)


def byte_lines(raw: bytes, count: int) -> tuple[list[str], int]:
    """The first ``count`` lines of a `plain_ascii` file (fewer if it has fewer), as `read_source` splits them, and
    the offset where the next line starts (`line_start`)."""
    start = line_start(raw, count)
    parts = _LINE_BREAK_BYTES_RE.split(raw[:start])
    if parts[-1] == b"":
        parts.pop()
    return [part.decode("ascii") for part in parts], start


def line_count(raw: bytes) -> int:
    """How many lines `read_source` finds in a `plain_ascii` file."""
    breaks = sum(1 for _ in _LINE_BREAK_BYTES_RE.finditer(raw)) if b"\r" in raw else raw.count(b"\n")
    return breaks + (not raw.endswith((b"\n", b"\r")))


def count_tokens(raw: bytes, start: int = 0) -> int:
    """Whitespace-separated tokens in ``raw`` from offset ``start``, counted without keeping one of them."""
    return sum(1 for _ in _TOKEN_BYTES_RE.finditer(raw, start))


def strict_numbers(raw: bytes, start: int = 0) -> bool:
    """True if every whitespace-separated token from offset ``start`` is a strict decimal number (as
    `TextSource.number` reads it, without a Fortran ``D`` exponent, NaN or infinity)."""
    return _BAD_TOKEN_BYTES_RE.search(raw, start) is None


def parse_numbers(raw: bytes, start: int, count: int) -> np.ndarray | None:
    """The ``count`` whitespace-separated numbers of ``raw`` from offset ``start`` (checked by `strict_numbers`),
    parsed by numpy `CHUNK_BYTES` at a time into one array; None if numpy finds another count."""
    out = np.empty(count)
    filled, at = 0, start
    while at < len(raw):
        cut = _SPACE_BYTES_RE.search(raw, min(at + CHUNK_BYTES, len(raw)))
        end = len(raw) if cut is None else cut.start()
        chunk = raw[at:end]
        at = end + 1
        if not chunk.strip():
            continue
        values = np.fromstring(chunk, sep=" ")
        if filled + values.size > count:
            return None
        out[filled:filled + values.size] = values
        filled += values.size
    return out if filled == count else None


def source_from(path: Path, raw: bytes, sha: str, expected: str) -> TextSource:
    """The `TextSource` of a record file's bytes ``raw`` (SHA-256 ``sha``), after checking them (see `read_source`)."""
    lines = _decoded(path, raw, expected).split("\n")
    if lines[-1] == "":
        lines.pop()
    return TextSource(path=path, lines=lines, sha256=sha)


def read_source(path: Path, expected: str) -> TextSource:
    """Read ``path`` as a text record file; ``expected`` describes its content for the empty-file error."""
    raw, sha = read_record(path)
    return source_from(path, raw, sha, expected)


def read_text_body(path: Path, expected: str) -> tuple[TextSource, str]:
    """Read ``path`` as a text record file without splitting it into lines (a record of millions of samples):
    a `TextSource` with no ``lines`` (for its errors and checksum) and the text, line breaks as LF."""
    raw = read_record_bytes(path, "a record file")
    sha = hashlib.sha256(raw).hexdigest()
    text = _decoded(path, raw, expected)
    return TextSource(path=path, lines=[], sha256=sha), text


def _as_float(value: float) -> float:
    """``value`` as a float; an int too large for one is infinite."""
    try:
        return float(value)
    except OverflowError:
        return math.inf


def given_dt(dt: float | None) -> float | None:
    """The time step the user gave (``--dt``) [s], checked finite and > 0; None if none was given."""
    if dt is None:
        return None
    if isinstance(dt, bool) or not isinstance(dt, int | float) or dt_problem(_as_float(dt)):
        raise RecordError(
            f"the given dt must be a number of seconds from {DT_MIN_S:g} to {DT_MAX_S:g}, got {dt!r}"
        )
    return float(dt)


def matching_dt(path: Path, line: int | None, in_file: float, given: float | None) -> float:
    """The file's dt [s], after checking that a given dt, if any, matches it (`DT_RTOL`)."""
    if given is not None and not math.isclose(in_file, given, rel_tol=DT_RTOL):
        raise located(
            path, line, f"the file gives dt = {in_file:g} s but dt = {given:g} s was given; expected the same dt"
        )
    return in_file


def agreed_dt(path: Path, line: int | None, in_file: float | None, given: float | None, missing: str) -> float:
    """The record's dt [s]: the file's (a given dt must match it), else the given one.

    ``missing`` ends the error when neither is known (what the file or the user should say).
    """
    if in_file is not None:
        return matching_dt(path, line, in_file, given)
    if given is None:
        raise located(path, line, f"no time step: {missing}")
    return given


def matching_unit(path: Path, line: int | None, in_file: str, given: str | None) -> str:
    """The file's canonical unit, after checking that a given unit, if any, is the same."""
    if given is not None and given != in_file:
        raise located(path, line, f"the file gives the unit {in_file} but {given} was given; expected the same unit")
    return in_file


def agreed_unit(path: Path, line: int | None, in_file: str | None, given: str | None, missing: str) -> str:
    """The record's canonical unit: the file's (a given unit must match it), else the given one."""
    if in_file is not None:
        return matching_unit(path, line, in_file, given)
    if given is None:
        raise located(path, line, f"no acceleration unit: {missing}")
    return given


# Rows of numbers separated by commas (CSV records), on the bytes of a `csv_ready` file: lines end in LF or CR LF.
_NUMBER = rb"[ \t]*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?[ \t]*"
#: A data line (neither blank nor a comment, whose first character after blanks is '#'), and any other line.
_DATA_LINE_BYTES_RE = re.compile(rb"^[ \t]*[^ \t\r\n#]", re.M)
_OTHER_LINE_BYTES_RE = re.compile(rb"^[ \t]*(?:#[^\n]*|\r?)$", re.M)
_COMMENT_LINE_BYTES_RE = re.compile(rb"^[ \t]*#[^\r\n]*", re.M)
_ODD_BYTES_RE = re.compile(rb"[\x0b\x0c\x1c-\x1f]|\r(?!\n)")


def csv_ready(raw: bytes) -> bool:
    """True if ``raw`` is `plain_ascii`, its lines end in LF or CR LF and it has no other whitespace than spaces and
    tabs (so its blank and comment lines are those `settings.is_comment` sees): a file `parse_rows` can read."""
    return plain_ascii(raw) and _ODD_BYTES_RE.search(raw) is None


def line_number(raw: bytes, offset: int) -> int:
    """The 1-based line of a `csv_ready` file that holds byte ``offset``."""
    return raw.count(b"\n", 0, offset) + 1


def comment_lines(raw: bytes) -> Iterator[tuple[int, str]]:
    """(line number, text) of each comment line of a `csv_ready` file, one at a time."""
    line, at = 1, 0
    for match in _COMMENT_LINE_BYTES_RE.finditer(raw):
        line += raw.count(b"\n", at, match.start())
        at = match.start()
        yield line, match.group().decode("ascii")


def first_data_line(raw: bytes, start: int = 0) -> int | None:
    """The offset of the first data line of a `csv_ready` file from ``start`` (a line start), or None."""
    match = _DATA_LINE_BYTES_RE.search(raw, start)
    return None if match is None else match.start()


def count_rows(raw: bytes, start: int = 0, end: int | None = None) -> int:
    """Data lines of a `csv_ready` file from offset ``start``, counted without keeping one of them."""
    return sum(1 for _ in _DATA_LINE_BYTES_RE.finditer(raw, start, len(raw) if end is None else end))


def strict_rows(raw: bytes, start: int, width: int) -> bool:
    """True if every data line of a `csv_ready` file from ``start`` is ``width`` strict decimal numbers (as
    `TextSource.number` reads them, without a ``D`` exponent) separated by commas, spaces and tabs around them."""
    row = _NUMBER + (rb"," + _NUMBER) * (width - 1)
    bad = re.compile(rb"^(?![ \t]*(?:#|\r?$))(?!" + row + rb"\r?$)", re.M)
    return bad.search(raw, start) is None


def parse_rows(raw: bytes, start: int, count: int, width: int) -> list[np.ndarray] | None:
    """The ``width`` columns of the ``count`` rows of a `csv_ready` file from offset ``start`` (checked by
    `strict_rows`), parsed by numpy `CHUNK_BYTES` at a time straight into one array per column; None if numpy finds
    another count."""
    columns = [np.empty(count) for _ in range(width)]
    filled, at = 0, start
    while at < len(raw):
        cut = raw.find(b"\n", min(at + CHUNK_BYTES, len(raw)))
        end = len(raw) if cut < 0 else cut + 1
        chunk = raw[at:end]
        at = end
        if b"#" in chunk:
            chunk = _COMMENT_LINE_BYTES_RE.sub(b"", chunk)
        chunk = chunk.replace(b",", b" ")
        if not chunk.strip():
            continue
        try:
            values = np.fromstring(chunk, sep=" ")
        except ValueError:  # not all numbers: `strict_rows` was not asked
            return None
        rows = values.size // width
        if rows * width != values.size or filled + rows > count:
            return None
        for i, column in enumerate(columns):
            column[filled:filled + rows] = values[i::width]
        filled += rows
    return columns if filled == count else None


class LineNumbers(Sequence[int]):
    """The line numbers of a record's ``_count`` data lines, each found by :meth:`_line` when it is asked for (an
    error names its line) rather than kept for every sample."""

    _count: int

    def _line(self, i: int) -> int:
        """The line number of data line ``i`` (0 ≤ i < ``_count``)."""
        raise NotImplementedError

    def __len__(self) -> int:
        return self._count

    @overload
    def __getitem__(self, index: int) -> int: ...
    @overload
    def __getitem__(self, index: slice) -> list[int]: ...
    def __getitem__(self, index: int | slice) -> int | list[int]:
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(self._count))]
        i = index + self._count if index < 0 else index
        if not 0 <= i < self._count:
            raise IndexError(index)
        return self._line(i)


class DataLines(LineNumbers):
    """The line number of each data line of a `csv_ready` file from an offset, without keeping the file: the first
    line's number and, for each blank or comment line among them, how many data lines come before it."""

    def __init__(self, raw: bytes, start: int, count: int) -> None:
        self._count = count
        first = first_data_line(raw, start)
        self._first = 0 if first is None else line_number(raw, first)
        self._gaps: array[int] = array("q")
        rows, at = 0, first or start
        for match in _OTHER_LINE_BYTES_RE.finditer(raw, at):
            if match.start() == len(raw):
                break
            rows += count_rows(raw, at, match.start())
            at = match.end()
            self._gaps.append(rows)

    def _line(self, i: int) -> int:
        return self._first + i + bisect.bisect_right(self._gaps, i)


class ByteLines(Sequence[str]):
    """The lines of a `plain_ascii` file as `read_source` splits them, decoded one at a time when one is asked for:
    the file's bytes and where each line starts (8 bytes a line), not a Python string per line."""

    def __init__(self, raw: bytes) -> None:
        self._raw = raw
        self._starts: array[int] = array("q", [0])
        self._starts.extend(match.end() for match in _LINE_BREAK_BYTES_RE.finditer(raw))
        if self._starts[-1] != len(raw):
            self._starts.append(len(raw))

    def __len__(self) -> int:
        return len(self._starts) - 1

    @overload
    def __getitem__(self, index: int) -> str: ...
    @overload
    def __getitem__(self, index: slice) -> list[str]: ...
    def __getitem__(self, index: int | slice) -> str | list[str]:
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        i = index + len(self) if index < 0 else index
        if not 0 <= i < len(self):
            raise IndexError(index)
        return self._raw[self._starts[i]:self._starts[i + 1]].rstrip(b"\r\n").decode("ascii")
