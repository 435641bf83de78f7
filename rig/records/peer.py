"""Minimal reader for PEER NGA ``.AT2`` acceleration files (NGA-West2 and the older NGA header).

Both styles have four header lines followed by the samples, several per line::

    PEER NGA STRONG MOTION DATABASE RECORD
    Imperial Valley-06, 10/15/1979, El Centro Array #6, 230
    ACCELERATION TIME SERIES IN UNITS OF G
    NPTS=   7995, DT=   .0050 SEC,                       <- NGA-West2
      4164    0.0100    NPTS, DT                          <- older NGA

The unit on line 3 may be G, CM/S/S (CM/S^2, CM/SEC/SEC, …) or M/S/S (M/S^2, …); values are converted
to g with g = 9.81 m/s². Any deviation (garbled header, non-numeric token, NaN, dt <= 0, a sample count
different from NPTS) raises `RecordError` naming the file, the line and what was expected: a record is
never silently truncated or padded.
"""

from __future__ import annotations

import hashlib
import math
import re
from pathlib import Path

import numpy as np

from .motion import G, GroundMotion, RecordError, array_sha256

_HEADER_LINES = 4
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][-+]?\d+)?"
_NUMBER_RE = re.compile(_NUMBER)
_WEST2_RE = re.compile(
    r"^\s*NPTS\s*=\s*(?P<npts>[^\s,]+)\s*,?\s*DT\s*=\s*(?P<dt>[-+]?[0-9.]+(?:[eEdD][-+]?\d+)?)", re.I
)
_OLD_RE = re.compile(r"^\s*(?P<npts>[^\s,]+)\s+(?P<dt>[^\s,]+)\s+NPTS\s*,?\s*DT\b", re.I)
_UNITS_RE = re.compile(r"UNITS\s+OF\s+(?P<units>\S+)", re.I)
_NONFINITE_RE = re.compile(r"^[-+]?(?:nan|inf|infinity)$", re.I)

#: Factor that converts a value in the file's unit to g, keyed by the normalised unit text.
_TO_G: dict[str, float] = {
    "G": 1.0,
    **{u: 0.01 / G for u in ("CM/S/S", "CM/S^2", "CM/S2", "CM/SEC/SEC", "CM/SEC^2", "CM/SEC2", "GAL")},
    **{u: 1.0 / G for u in ("M/S/S", "M/S^2", "M/S2", "M/SEC/SEC", "M/SEC^2", "M/SEC2")},
}
_UNIT_LIST = "G, CM/S/S, CM/S^2, CM/SEC/SEC, M/S/S, M/S^2"


def _fail(path: Path, line: int | None, message: str) -> RecordError:
    """A `RecordError` that starts with ``file:line:`` (or ``file:``)."""
    where = f"{path}:{line}" if line is not None else f"{path}"
    return RecordError(f"{where}: {message}")


def _parse_number(path: Path, line: int, token: str, what: str) -> float:
    """One strict decimal number (Fortran ``D`` exponents allowed); else `RecordError` for that line."""
    if _NONFINITE_RE.match(token):
        raise _fail(path, line, f"{what} is {token!r}; expected a finite number")
    if not _NUMBER_RE.fullmatch(token):
        raise _fail(path, line, f"{what} {token!r} is not a number")
    return float(token.replace("d", "e").replace("D", "e"))


def _units_factor(path: Path, line3: str) -> tuple[str, float]:
    """Unit text of header line 3 and the factor that converts it to g."""
    if "ACCEL" not in line3.upper():
        raise _fail(
            path, 3,
            "expected an acceleration header like 'ACCELERATION TIME SERIES IN UNITS OF G', "
            f"got {line3.strip()!r}",
        )
    match = _UNITS_RE.search(line3)
    if match is None:
        raise _fail(path, 3, f"expected 'IN UNITS OF <unit>' ({_UNIT_LIST}), got {line3.strip()!r}")
    unit = match["units"].upper().rstrip(".,;")
    if unit not in _TO_G:
        raise _fail(path, 3, f"unknown acceleration unit {unit!r}; expected one of {_UNIT_LIST}")
    return unit, _TO_G[unit]


def _npts_dt(path: Path, line4: str) -> tuple[int, float, str]:
    """NPTS, DT [s] and the header style from header line 4."""
    match = _WEST2_RE.match(line4)
    style = "PEER NGA-West2 AT2"
    if match is None:
        match = _OLD_RE.match(line4)
        style = "PEER NGA AT2"
    if match is None:
        raise _fail(
            path, 4,
            "expected 'NPTS= <n>, DT= <dt> SEC' (NGA-West2) or '<n> <dt> NPTS, DT' (NGA), "
            f"got {line4.strip()!r}",
        )
    npts_text = match["npts"]
    if not npts_text.isdigit():
        raise _fail(path, 4, f"NPTS {npts_text!r} is not a positive integer")
    npts = int(npts_text)
    dt = _parse_number(path, 4, match["dt"], "DT")
    if npts <= 0:
        raise _fail(path, 4, f"NPTS must be > 0, got {npts}")
    if not math.isfinite(dt) or dt <= 0.0:
        raise _fail(path, 4, f"DT must be > 0 s, got {match['dt']!r}")
    return npts, dt, style


def _samples(path: Path, lines: list[str], first_line: int) -> tuple[list[float], int]:
    """All numbers of the data lines and the number of the last line that held data (1-based)."""
    values: list[float] = []
    last = first_line - 1
    for lineno, text in enumerate(lines, start=first_line):
        tokens = text.split()
        for col, token in enumerate(tokens, start=1):
            values.append(_parse_number(path, lineno, token, f"token {col} of the line"))
        if tokens:
            last = lineno
    return values, last


def _decode_lines(path: Path) -> tuple[list[str], str]:
    """Lines of the file (any line ending) and the SHA-256 of its bytes."""
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise _fail(path, None, "no such file") from None
    except OSError as exc:
        raise _fail(path, None, f"cannot read ({exc.strerror or exc})") from None
    return raw.decode("latin-1").splitlines(), hashlib.sha256(raw).hexdigest()


def read_at2(path: str | Path) -> GroundMotion:
    """Read a PEER ``.AT2`` file into a `GroundMotion` (acceleration converted to g, dt in s).

    The motion's name is the file stem; ``provenance`` holds the path, header style, title line,
    file unit and conversion factor, NPTS, DT, ``sha256`` of the float64 values [g] and
    ``source_sha256`` of the file's bytes.
    """
    path = Path(path)
    lines, file_sha = _decode_lines(path)
    if len(lines) < _HEADER_LINES:
        raise _fail(
            path, len(lines) + 1,
            f"expected a {_HEADER_LINES}-line PEER header (title, event, units, NPTS/DT); "
            f"the file has only {len(lines)} line(s)",
        )
    unit, factor = _units_factor(path, lines[2])
    npts, dt, style = _npts_dt(path, lines[3])
    values, last = _samples(path, lines[_HEADER_LINES:], _HEADER_LINES + 1)
    if len(values) != npts:
        kind = "truncated data" if len(values) < npts else "extra data"
        raise _fail(
            path, max(last, _HEADER_LINES),
            f"{kind}: line 4 declares NPTS={npts} but the file holds {len(values)} values "
            f"(lines {_HEADER_LINES + 1}-{max(last, _HEADER_LINES)})",
        )
    acc = np.asarray(values, dtype=np.float64) * factor
    provenance = {
        "source": "file",
        "path": str(path.resolve()),
        "file": path.name,
        "format": style,
        "title": lines[1].strip(),
        "units_in_file": unit,
        "to_g": factor,
        "npts": npts,
        "dt": dt,
        "sha256": array_sha256(acc),
        "source_sha256": file_sha,
    }
    return GroundMotion(name=path.stem, dt=dt, acc_h=acc, provenance=provenance)
