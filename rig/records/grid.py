"""The time column of a plain-text or CSV record: it must be evenly spaced, and it gives dt [s].

Times must increase, and every time ``t_i`` must lie within `GRID_TOLERANCE` · dt of the even grid
``t_0 + i · dt`` with ``dt = (t_last - t_0) / (npts - 1)``; the first time that does not is reported with
its line (a missing or extra sample shows up there or a little later). dt is rounded to 12 significant
digits, so that times printed in decimal give back the decimal dt. The first time ``t_0`` need
not be 0; the motion's own clock starts at 0 at the first sample and ``t_0`` goes into its provenance.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .settings import Settings
from .source import DT_RTOL, TextSource, dt_problem

#: Largest distance of a time from the even grid, as a fraction of dt.
GRID_TOLERANCE = 0.01


def time_step(src: TextSource, times: np.ndarray, lines: Sequence[int], settings: Settings) -> tuple[float, float]:
    """dt [s] and the first time t_0 [s] of an evenly spaced time column; ``lines[i]`` holds ``times[i]``.

    A ``# dt`` setting, if any, must agree with the column's dt (relative tolerance `DT_RTOL`).
    """
    n = times.size
    if n < 2:
        raise src.error(
            lines[0], "a time column needs at least 2 samples to give dt; expected more samples "
            "(or only an acceleration column and a given dt)",
        )
    with np.errstate(over="ignore", invalid="ignore"):  # one temporary array at a time (a record of millions)
        steps = np.diff(times)
        back = np.flatnonzero(~(steps > 0.0))
        del steps
        if back.size:
            j = int(back[0]) + 1
            raise src.error(
                lines[j], f"time {times[j]:g} s does not increase (line {lines[j - 1]} has {times[j - 1]:g} s); "
                "expected increasing, evenly spaced times",
            )
        spacing = (times[-1] - times[0]) / (n - 1)  # > 0: the times increase strictly
        if not math.isfinite(spacing):
            raise src.error(
                lines[-1], f"the time column spans {times[0]:g} s to {times[-1]:g} s; expected a finite dt"
            )
        distance = np.arange(n, dtype=np.float64)  # the even grid t0 + i * spacing, then each time's distance to it
        distance *= spacing
        distance += times[0]
        np.subtract(times, distance, out=distance)
        np.abs(distance, out=distance)
        off = np.flatnonzero(~(distance <= GRID_TOLERANCE * spacing))
        del distance
        if off.size:
            i = int(off[0])
            grid = times[0] + np.float64(i) * spacing
            raise src.error(
                lines[i], f"uneven time column: t = {times[i]:g} s, expected {grid:g} s "
                f"(t0 + {i} x {spacing:g} s, within {GRID_TOLERANCE:.0%} of dt)",
            )
    dt = float(f"{spacing:.12g}")
    problem = dt_problem(dt)
    if problem:
        raise src.error(lines[1], f"the time column's step {dt:g} s {problem}")
    if settings.dt is not None and not math.isclose(settings.dt, dt, rel_tol=DT_RTOL):
        raise src.error(
            settings.dt_line, f"dt = {settings.dt:g} s but the time column is spaced {dt:g} s; expected the same dt"
        )
    return dt, float(times[0])
