"""Minimal reader for PEER NGA ``.AT2`` acceleration files (NGA-West2 and the older NGA header).

Both styles have four header lines followed by the samples, several per line::

    PEER NGA STRONG MOTION DATABASE RECORD
    Imperial Valley-06, 10/15/1979, El Centro Array #6, 230
    ACCELERATION TIME SERIES IN UNITS OF G
    NPTS=   7995, DT=   .0050 SEC,                       <- NGA-West2
      4164    0.0100    NPTS, DT                          <- older NGA

The unit on line 3 may be G, CM/S/S (CM/S^2, CM/SEC/SEC, GAL, …), M/S/S (M/S^2, …) or MM/S/S (see
`units`); values are converted to g with g = 9.81 m/s². Samples are whitespace-separated decimal numbers
(``.1234567E-02``, ``-.220000E-03``, Fortran ``D`` exponents), any number a line; lines may end in LF,
CRLF or CR. Any deviation (garbled header, non-numeric token, NaN, overflow, an implausible
acceleration above 100 g, dt <= 0, a sample count different from NPTS, bytes that are not UTF-8 text)
raises `RecordError` naming the file, the line and what was expected: a record is never silently
truncated or padded.

The component (horizontal or vertical) comes from the word after the last comma of line 2 and from the file
name (`component.peer_component`), in ``provenance["component"]``.

Memory: a file of ASCII text whose values are all strict decimal numbers (the usual case) is parsed from its bytes
by numpy, a chunk at a time, into one array, never one Python object per value (``benchmarks/record_memory.py``
measures the peak per sample). Any other file (a Fortran ``D`` exponent, a bad token, a value out of range, a count
that is not NPTS, bytes that are not ASCII) is read line by line with the exact checks, which either give the same
array or stop at the first bad value with its ``FILE:LINE`` error. At most `source.MAX_SAMPLES` values: they are
counted before one is parsed.
"""

from __future__ import annotations

import re
from array import array
from pathlib import Path

import numpy as np

from .component import peer_component
from .motion import GroundMotion, array_sha256
from .source import (
    MAX_ABS_G,
    MAX_SAMPLES,
    TextSource,
    byte_lines,
    count_tokens,
    given_dt,
    line_count,
    line_start,
    located,
    matching_dt,
    matching_unit,
    parse_numbers,
    plain_ascii,
    read_record,
    source_from,
    strict_numbers,
)
from .units import TO_G, UNIT_HELP, given_unit, parse_unit

_HEADER_LINES = 4
_WEST2_RE = re.compile(
    r"^\s*NPTS\s*=\s*(?P<npts>[^\s,]+)\s*,?\s*DT\s*=\s*(?P<dt>[-+]?[0-9.]+(?:[eEdD][-+]?\d+)?)", re.I
)
_OLD_RE = re.compile(r"^\s*(?P<npts>[^\s,]+)\s+(?P<dt>[^\s,]+)\s+NPTS\s*,?\s*DT\b", re.I)
_UNITS_RE = re.compile(r"UNITS\s+OF\s+(?P<units>\S+)", re.I)
_EXPECTED = "a PEER .AT2 file: a 4-line header (title, event, units, NPTS/DT) and the samples"


def _units(src: TextSource) -> tuple[str, str]:
    """Unit text of header line 3 as written and its canonical name (a key of `TO_G`)."""
    line3 = src.lines[2]
    if "ACCEL" not in line3.upper():
        raise src.error(
            3,
            "expected an acceleration header like 'ACCELERATION TIME SERIES IN UNITS OF G', "
            f"got {line3.strip()!r}",
        )
    match = _UNITS_RE.search(line3)
    if match is None:
        raise src.error(3, f"expected 'IN UNITS OF <unit>' ({UNIT_HELP.upper()}), got {line3.strip()!r}")
    text = match["units"].upper().rstrip(".,;")
    unit = parse_unit(text)
    if unit is None:
        raise src.error(3, f"unknown acceleration unit {text!r}; expected one of {UNIT_HELP.upper()}")
    return text, unit


def _npts_dt(src: TextSource) -> tuple[int, float, str]:
    """NPTS, DT [s] and the header style from header line 4."""
    line4 = src.lines[3]
    match = _WEST2_RE.match(line4)
    style = "PEER NGA-West2 AT2"
    if match is None:
        match = _OLD_RE.match(line4)
        style = "PEER NGA AT2"
    if match is None:
        raise src.error(
            4,
            "expected 'NPTS= <n>, DT= <dt> SEC' (NGA-West2) or '<n> <dt> NPTS, DT' (NGA), "
            f"got {line4.strip()!r}",
        )
    npts_text = match["npts"]
    if not re.fullmatch(r"[0-9]+", npts_text) or int(npts_text) == 0:
        raise src.error(4, f"NPTS {npts_text!r} is not a positive integer; expected the number of samples")
    dt = src.check_dt(4, src.number(4, match["dt"], "DT"), match["dt"], label="DT")
    return int(npts_text), dt, style


def _samples(src: TextSource, to_g: float, unit: str) -> tuple[array[float], int]:
    """All samples [g] after the header and the number of the last line that held data (1-based), line by line
    with the exact checks (`TextSource.acceleration`), into an array (8 bytes a sample, no Python float kept)."""
    values: array[float] = array("d")
    last = _HEADER_LINES
    for lineno, text in enumerate(src.lines[_HEADER_LINES:], start=_HEADER_LINES + 1):
        tokens = text.split()
        for col, token in enumerate(tokens, start=1):
            values.append(src.acceleration(lineno, token, f"token {col} of the line", to_g, unit))
        if tokens:
            last = lineno
    return values, last


def read_at2(path: str | Path, *, dt: float | None = None, units: str | None = None) -> GroundMotion:
    """Read a PEER ``.AT2`` file into a `GroundMotion` (acceleration converted to g, dt in s).

    ``dt`` [s] and ``units``, if given, must agree with the header (the header is what counts). The
    motion's name is the file stem; ``provenance`` holds the path, header style, title line, line count,
    file unit and conversion factor, NPTS, DT, ``sha256`` of the float64 values [g] and ``source_sha256``
    of the file's bytes.
    """
    path = Path(path)
    dt, units = given_dt(dt), given_unit(units)
    raw, sha = read_record(path)
    clean = plain_ascii(raw)
    if clean:  # the header from the bytes: the samples are parsed from them too, without a copy of the file
        header, body = byte_lines(raw, _HEADER_LINES)
        src, n_lines = TextSource(path=path, lines=header, sha256=sha), line_count(raw)
    else:  # decoded and split into lines, which says what is wrong with the bytes if anything is
        src = source_from(path, raw, sha, _EXPECTED)
        n_lines = len(src.lines)
    if n_lines < _HEADER_LINES:
        raise src.error(
            n_lines + 1,
            f"expected a {_HEADER_LINES}-line PEER header (title, event, units, NPTS/DT); "
            f"the file has only {n_lines} line(s)",
        )
    unit_text, unit = _units(src)
    matching_unit(path, 3, unit, units)
    npts, file_dt, style = _npts_dt(src)
    matching_dt(path, 4, file_dt, dt)
    to_g = TO_G[unit]
    if not clean:
        body = line_start(raw, _HEADER_LINES)
    count = count_tokens(raw, body)
    if count > MAX_SAMPLES:
        raise located(path, None, f"the record has {count:,} samples (values after the header); expected at most "
                                  f"{MAX_SAMPLES:,} (refused before parsing them)")
    acc = parse_numbers(raw, body, count) if clean and count == npts and strict_numbers(raw, body) else None
    if acc is not None:
        acc *= to_g
        if not (acc.min() >= -MAX_ABS_G and acc.max() <= MAX_ABS_G):  # NaN too: the exact check says which
            acc = None
    if acc is None and clean:  # a bad token or value, or a count that is not NPTS: line by line says where
        src = source_from(path, raw, sha, _EXPECTED)
    del raw
    if acc is None:
        values, last = _samples(src, to_g, unit_text)
        if len(values) != npts:
            kind = "truncated data" if len(values) < npts else "extra data"
            raise src.error(
                last,
                f"{kind}: line 4 declares NPTS={npts} but the file holds {len(values)} values "
                f"(lines {_HEADER_LINES + 1}-{last}); expected {npts} values",
            )
        acc = np.frombuffer(values, dtype=np.float64).copy()
        del values
    provenance = {
        "source": "file",
        "path": str(path.resolve()),
        "file": path.name,
        "format": style,
        "title": src.lines[1].strip(),
        "component": peer_component(src.lines[1], path),
        "lines": n_lines,
        "units_in_file": unit_text,
        "to_g": TO_G[unit],
        "npts": npts,
        "dt": file_dt,
        "sha256": array_sha256(acc),
        "source_sha256": sha,
    }
    return GroundMotion(name=path.stem, dt=file_dt, acc_h=acc, provenance=provenance)
