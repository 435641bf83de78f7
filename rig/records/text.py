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
* The component (horizontal or vertical) comes from the file name only (``….HNZ.txt``, ``…-UP.txt``, see
  `component`); a name that does not say gives a `RecordWarning`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .component import from_name
from .grid import time_step
from .motion import GroundMotion, array_sha256
from .settings import check_npts, is_comment, read_settings
from .source import TextSource, agreed_dt, agreed_unit, given_dt, matching_dt, read_source
from .units import TO_G, given_unit

_EXPECTED = "samples: one column (acceleration) or two (time [s], acceleration) a line, '#' comments"


def read_text(path: str | Path, *, dt: float | None = None, units: str | None = None) -> GroundMotion:
    """Read a plain-text record (see the module docstring) into a `GroundMotion` [g, s].

    Args:
        path: the file.
        dt: time step [s] for a file that does not give one (must agree with the file if it does).
        units: acceleration unit of the samples if the file has no ``# units`` line (e.g. ``"cm/s/s"``).
    """
    path = Path(path)
    dt, units = given_dt(dt), given_unit(units)
    src = read_source(path, _EXPECTED)
    settings = read_settings(src)
    rows = _rows(src)
    unit = agreed_unit(
        path, settings.unit_line, settings.unit, units,
        "expected a '# units = …' line in the file or a given unit (--units g|cm/s/s|m/s/s)",
    )
    columns = len(rows[0][1])
    index = columns - 1
    acc = np.array(
        [src.acceleration(line, tokens[index], "the acceleration", TO_G[unit], unit) for line, tokens in rows]
    )
    check_npts(src, settings, [line for line, _ in rows])
    provenance_dt: dict[str, object]
    if columns == 1:
        dt = agreed_dt(
            path, settings.dt_line, settings.dt, dt,
            "a one-column file needs a '# dt = …' line or a given dt (--dt S)",
        )
        provenance_dt = {"dt_from": "given" if settings.dt is None else "file"}
    else:
        lines = [line for line, _ in rows]
        times = np.array([src.number(line, tokens[0], "the time") for line, tokens in rows])
        column_dt, t0 = time_step(src, times, lines, settings)
        dt = matching_dt(path, lines[0], column_dt, dt)
        provenance_dt = {"dt_from": "time column", "t0": t0}
    provenance = {
        "source": "file",
        "path": str(path.resolve()),
        "file": path.name,
        "format": "plain text, " + ("acceleration" if columns == 1 else "time and acceleration"),
        "component": from_name(path, "a plain text file names no component"),
        "lines": len(src.lines),
        "units_in_file": settings.unit_text or unit,
        "units_from": "given" if settings.unit is None else "file",
        "to_g": TO_G[unit],
        "npts": int(acc.size),
        "dt": dt,
        **provenance_dt,
        "sha256": array_sha256(acc),
        "source_sha256": src.sha256,
    }
    return GroundMotion(name=path.stem, dt=dt, acc_h=acc, provenance=provenance)


def _rows(src: TextSource) -> list[tuple[int, list[str]]]:
    """(line, tokens) of every data line; all with the first data line's column count (1 or 2)."""
    rows: list[tuple[int, list[str]]] = []
    for lineno, text in enumerate(src.lines, start=1):
        tokens = text.split()
        if not tokens or is_comment(text):
            continue
        if not rows and len(tokens) > 2:
            raise src.error(
                lineno, f"{len(tokens)} columns; expected 1 (acceleration) or 2 (time [s], acceleration) "
                "(use a CSV file with named columns for more channels)",
            )
        if rows and len(tokens) != len(rows[0][1]):
            first = rows[0][0]
            raise src.error(
                lineno, f"{len(tokens)} column(s); expected {len(rows[0][1])} like line {first}, the first data line"
            )
        rows.append((lineno, tokens))
    if not rows:
        raise src.error(len(src.lines), f"no samples; expected {_EXPECTED}")
    return rows

