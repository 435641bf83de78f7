"""Reader for plain-text records (``.txt``, ``.dat``, ``.acc``): one or two whitespace-separated columns.

::

    # El Centro 1940 N-S, digitised          <- free-text comment
    # dt = 0.02 s                            <- settings (see `settings`): dt, units, npts
    # units = cm/s/s
    0.0   -1.20
    0.02   3.41                              <- time [s], acceleration  (or acceleration only)

* One column: accelerations. dt comes from a ``# dt = …`` line or from the caller (``--dt``).
* Two columns: time [s] and acceleration. dt comes from the time column, which must increase and be
  evenly spaced (within 1 % of dt, see `grid`); a ``# dt`` line or a given dt must agree with it.
* The acceleration unit comes from a ``# units = …`` line or from the caller (``--units``); with both, they
  must agree. Values are converted to g.
* Blank lines and ``#`` comments may stand anywhere; every other line holds the same number of columns.
* A file cut off at the end of a line looks like a shorter record: give ``# npts = …`` and the reader
  checks the count.
* At most `source.MAX_SAMPLES` samples: the data lines are counted before a number is parsed.
* The component (horizontal or vertical) comes from the file name only (``….HNZ.txt``, ``…-UP.txt``, see
  `component`); a name that does not say gives a `RecordWarning`.

Memory: the samples are parsed into arrays by numpy's reader (``np.loadtxt``), never one Python object per line
(``benchmarks/record_memory.py`` measures the peak per sample). A file numpy's reader does not take (a Fortran
``D`` exponent, a bad token, a column too many) is read again line by line, one line at a time, which either
fills the same arrays or stops at the first bad line with its ``FILE:LINE`` error.
"""

from __future__ import annotations

import io
import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from .component import from_name
from .grid import time_step
from .motion import GroundMotion, array_sha256
from .settings import check_npts, read_settings
from .source import (
    MAX_ABS_G,
    MAX_SAMPLES,
    LineNumbers,
    TextSource,
    agreed_dt,
    agreed_unit,
    given_dt,
    located,
    matching_dt,
    read_text_body,
)
from .units import TO_G, given_unit

_EXPECTED = "samples: one column (acceleration) or two (time [s], acceleration) a line, '#' comments"
#: A comment line, and a data line (neither blank nor a comment), in text whose line breaks are LF.
_COMMENT_RE = re.compile(r"^[^\S\n]*#[^\n]*", re.M)
_DATA_RE = re.compile(r"^[^\S\n]*[^\s#][^\n]*", re.M)


def _numbered(text: str, pattern: re.Pattern[str]) -> Iterator[tuple[int, str]]:
    """(line number, text) of each line of ``text`` that ``pattern`` matches, one at a time."""
    line, at = 1, 0
    for match in pattern.finditer(text):
        line += text.count("\n", at, match.start())
        at = match.start()
        yield line, match.group()


class _DataLines(LineNumbers):
    """The line number of each data line, found by scanning the text when one is asked for (on an error)."""

    def __init__(self, text: str, count: int) -> None:
        self._text = text
        self._count = count

    def _line(self, i: int) -> int:
        for k, (line, _) in enumerate(_numbered(self._text, _DATA_RE)):
            if k == i:
                return line
        raise IndexError(i)


def _check_columns(src: TextSource, text: str) -> int:
    """The column count (1 or 2) of every data line; the first line that differs is an error."""
    first: tuple[int, int] | None = None
    for lineno, line in _numbered(text, _DATA_RE):
        columns = len(line.split())
        if first is None:
            if columns > 2:
                raise src.error(
                    lineno, f"{columns} columns; expected 1 (acceleration) or 2 (time [s], acceleration) "
                    "(use a CSV file with named columns for more channels)",
                )
            first = (lineno, columns)
        elif columns != first[1]:
            raise src.error(
                lineno, f"{columns} column(s); expected {first[1]} like line {first[0]}, the first data line"
            )
    assert first is not None  # the caller counted the data lines
    return first[1]


def _parse_lines(src: TextSource, text: str, count: int, columns: int, to_g: float, unit: str) -> np.ndarray:
    """(count, columns) values, line by line with the exact checks (`TextSource.number`, `.acceleration`)."""
    out = np.empty((count, columns))
    for k, (lineno, line) in enumerate(_numbered(text, _DATA_RE)):
        tokens = line.split()
        if columns == 2:
            out[k, 0] = src.number(lineno, tokens[0], "the time")
        out[k, -1] = src.acceleration(lineno, tokens[-1], "the acceleration", to_g, unit)
    return out


def read_text(path: str | Path, *, dt: float | None = None, units: str | None = None) -> GroundMotion:
    """Read a plain-text record (see the module docstring) into a `GroundMotion` [g, s].

    Args:
        path: the file.
        dt: time step [s] for a file that does not give one (must agree with the file if it does).
        units: acceleration unit of the samples if the file has no ``# units`` line (e.g. ``"cm/s/s"``).
    """
    path = Path(path)
    dt, units = given_dt(dt), given_unit(units)
    src, text = read_text_body(path, _EXPECTED)
    settings = read_settings(src, _numbered(text, _COMMENT_RE))
    count = sum(1 for _ in _DATA_RE.finditer(text))
    n_lines = text.count("\n") + (not text.endswith("\n"))
    if count == 0:
        raise src.error(n_lines, f"no samples; expected {_EXPECTED}")
    if count > MAX_SAMPLES:
        raise located(path, None, f"the record has {count:,} samples (data lines); expected at most {MAX_SAMPLES:,} "
                                  "(refused before parsing them)")
    try:
        values: np.ndarray | None = np.loadtxt(io.BytesIO(text.encode()), comments="#", ndmin=2, dtype=np.float64,
                                               encoding="utf-8")
    except ValueError:
        values = None
    columns = _check_columns(src, text) if values is None or values.shape[1] > 2 else values.shape[1]
    unit = agreed_unit(
        path, settings.unit_line, settings.unit, units,
        "expected a '# units = …' line in the file or a given unit (--units g|cm/s/s|m/s/s)",
    )
    to_g = TO_G[unit]
    if values is not None:
        values[:, -1] *= to_g
        bad = np.flatnonzero(~np.isfinite(values).all(axis=1) | ~(np.abs(values[:, -1]) <= MAX_ABS_G))
        if bad.size:  # the exact check of that line says what is wrong with it
            values = None
    if values is None:
        values = _parse_lines(src, text, count, columns, to_g, unit)
    acc = np.ascontiguousarray(values[:, -1])
    lines = _DataLines(text, count)
    check_npts(src, settings, lines)
    provenance_dt: dict[str, object]
    if columns == 1:
        dt = agreed_dt(
            path, settings.dt_line, settings.dt, dt,
            "a one-column file needs a '# dt = …' line or a given dt (--dt S)",
        )
        provenance_dt = {"dt_from": "given" if settings.dt is None else "file"}
    else:
        column_dt, t0 = time_step(src, np.ascontiguousarray(values[:, 0]), lines, settings)
        dt = matching_dt(path, lines[0], column_dt, dt)
        provenance_dt = {"dt_from": "time column", "t0": t0}
    del values
    provenance = {
        "source": "file",
        "path": str(path.resolve()),
        "file": path.name,
        "format": "plain text, " + ("acceleration" if columns == 1 else "time and acceleration"),
        "component": from_name(path, "a plain text file names no component"),
        "lines": n_lines,
        "units_in_file": settings.unit_text or unit,
        "units_from": "given" if settings.unit is None else "file",
        "to_g": to_g,
        "npts": int(acc.size),
        "dt": dt,
        **provenance_dt,
        "sha256": array_sha256(acc),
        "source_sha256": src.sha256,
    }
    return GroundMotion(name=path.stem, dt=dt, acc_h=acc, provenance=provenance)
