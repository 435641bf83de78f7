"""The paper's Fig. 13: controlled overturning rate per angle, analytical against experimental.

**Cases.** One case is one body on the plate in one completed run: the analysis's predicted direction (per
model) and the experiment's observed one (+1 low side, −1 high side, 0 did not overturn; ARCHITECTURE §2).

**COR** (controlled overturning rate, as the paper's EXPERIMENTAL RESULTS and ARCHITECTURE §2 define it): among
the cases that *overturned*, the fraction that overturned towards the low (desired) side::

    COR = #(direction = +1) / #(direction ≠ 0)

counted separately for the analysis (predicted directions) and for the experiment (observed directions). A case
that did not overturn (direction 0) enters neither count of that side — the paper's rates hold "assuming that
it will overturn" — so a body that overturned in the analysis but not on the table (or the reverse) counts
in the analysis's COR only (or the experiment's only); the counts beside every rate show it. A COR with no
overturn is undefined (NaN here, ``null`` in JSON), and so is a difference involving one.

**Rows.** Per model, angle and body (``body_id`` ≥ 1): ``runs`` = completed runs with that body at that angle;
the counts; ``difference = cor_analysis − cor_experiment`` (signed, fraction, not percent). Per model and angle
an **average** row (``body_id = 0``, the paper's "average results for all the bodies"): counts and ``runs``
summed over the bodies (body-runs), ``cor_analysis`` and ``cor_experiment`` the mean of the bodies' defined
CORs, ``difference`` theirs.

**Statistics.** Beside every COR its 95 % Wilson interval (``*_low``, ``*_high``, from the counts: for the average
row the pooled counts of its bodies), and per row ``p_value``: Fisher's exact test that analysis and experiment
share one rate (``analysis.proportions``; NaN where a COR is undefined). A difference is **beyond chance** when
p < 0.05: with three cases one overturn moves a rate by 33 points, which alone says nothing.
**max_difference** per model: the largest |difference| over the per-body rows
(the paper: "a maximum of 5 % difference … for a given angle and specific body"), None if none is defined.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass

import numpy as np

from analysis.proportions import SIGNIFICANCE, exact_two_proportions, wilson_interval

#: Compound layout of the ``/analysis/fig13`` dataset.
FIG13_DTYPE = np.dtype([
    ("angle_deg", "<f8"), ("body_id", "<i4"), ("model", "S16"), ("runs", "<i4"),
    ("overturned_analysis", "<i4"), ("towards_low_analysis", "<i4"), ("cor_analysis", "<f8"),
    ("overturned_experiment", "<i4"), ("towards_low_experiment", "<i4"), ("cor_experiment", "<f8"),
    ("difference", "<f8"), ("cor_analysis_low", "<f8"), ("cor_analysis_high", "<f8"),
    ("cor_experiment_low", "<f8"), ("cor_experiment_high", "<f8"), ("p_value", "<f8"),
])

ANGLE_DIGITS = 6
"""Angles are grouped after rounding to this many decimals of a degree."""


@dataclass(frozen=True)
class Case:
    """One body in one run for one model: angle [deg], body, model, predicted and observed direction."""

    angle_deg: float
    body_id: int
    model: str
    predicted: int
    observed: int


@dataclass(frozen=True)
class Fig13Row:
    """One row of the comparison (module docstring); rates are fractions in [0, 1] or NaN."""

    angle_deg: float
    body_id: int
    model: str
    runs: int
    overturned_analysis: int
    towards_low_analysis: int
    cor_analysis: float
    overturned_experiment: int
    towards_low_experiment: int
    cor_experiment: float
    difference: float
    cor_analysis_low: float = math.nan
    cor_analysis_high: float = math.nan
    cor_experiment_low: float = math.nan
    cor_experiment_high: float = math.nan
    p_value: float = math.nan
    """Fisher's exact test of equal rates (module docstring); NaN where a COR is undefined."""

    @property
    def beyond_chance(self) -> bool:
        """Whether analysis and experiment differ beyond chance (p < :data:`analysis.proportions.SIGNIFICANCE`)."""
        return not math.isnan(self.p_value) and self.p_value < SIGNIFICANCE

    def to_json(self) -> dict:
        """JSON-ready (NaN → None)."""
        return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in asdict(self).items()}


def cor(towards_low: int, overturned: int) -> float:
    """towards_low / overturned, NaN when nothing overturned."""
    return towards_low / overturned if overturned else math.nan


def _nanmean(values: list[float]) -> float:
    defined = [v for v in values if not math.isnan(v)]
    return sum(defined) / len(defined) if defined else math.nan


def fig13_rows(cases: Iterable[Case]) -> list[Fig13Row]:
    """The comparison rows, ordered by model (first seen), angle, then body (average row first)."""
    groups: dict[tuple[str, float, int], list[Case]] = {}
    models: list[str] = []
    for case in cases:
        if case.model not in models:
            models.append(case.model)
        key = (case.model, round(case.angle_deg, ANGLE_DIGITS), case.body_id)
        groups.setdefault(key, []).append(case)
    rows: list[Fig13Row] = []
    for model in models:
        for angle in sorted({a for m, a, _ in groups if m == model}):
            bodies = sorted(b for m, a, b in groups if m == model and a == angle)
            per_body = [_row(angle, body, model, groups[(model, angle, body)]) for body in bodies]
            rows.append(_average(angle, model, per_body))
            rows.extend(per_body)
    return rows


def _row(angle: float, body_id: int, model: str, cases: list[Case]) -> Fig13Row:
    over_a = sum(1 for c in cases if c.predicted != 0)
    low_a = sum(1 for c in cases if c.predicted == 1)
    over_e = sum(1 for c in cases if c.observed != 0)
    low_e = sum(1 for c in cases if c.observed == 1)
    cor_a, cor_e = cor(low_a, over_a), cor(low_e, over_e)
    return Fig13Row(angle, body_id, model, len(cases), over_a, low_a, cor_a, over_e, low_e, cor_e, cor_a - cor_e,
                    *_statistics(low_a, over_a, low_e, over_e))


def _statistics(low_a: int, over_a: int, low_e: int, over_e: int) -> tuple[float, float, float, float, float]:
    """The Wilson intervals of both rates and the exact test's p-value (module docstring)."""
    return (*wilson_interval(low_a, over_a), *wilson_interval(low_e, over_e),
            exact_two_proportions(low_a, over_a, low_e, over_e))


def _average(angle: float, model: str, rows: list[Fig13Row]) -> Fig13Row:
    cor_a = _nanmean([r.cor_analysis for r in rows])
    cor_e = _nanmean([r.cor_experiment for r in rows])
    over_a, low_a = sum(r.overturned_analysis for r in rows), sum(r.towards_low_analysis for r in rows)
    over_e, low_e = sum(r.overturned_experiment for r in rows), sum(r.towards_low_experiment for r in rows)
    return Fig13Row(angle, 0, model, sum(r.runs for r in rows), over_a, low_a, cor_a, over_e, low_e, cor_e,
                    cor_a - cor_e, *_statistics(low_a, over_a, low_e, over_e))


def max_difference(rows: Iterable[Fig13Row]) -> dict[str, float | None]:
    """Per model, the largest |difference| over the per-body rows (None when no difference is defined)."""
    out: dict[str, float | None] = {}
    for row in rows:
        out.setdefault(row.model, None)
        if row.body_id == 0 or math.isnan(row.difference):
            continue
        current = out[row.model]
        out[row.model] = abs(row.difference) if current is None else max(current, abs(row.difference))
    return out


def beyond_chance(rows: Iterable[Fig13Row]) -> dict[str, tuple[int, int]]:
    """Per model, (per-body rows that differ beyond chance, per-body rows where both CORs are defined)."""
    out: dict[str, tuple[int, int]] = {}
    for row in rows:
        differ, tested = out.get(row.model, (0, 0))
        if row.body_id != 0 and not math.isnan(row.p_value):
            differ, tested = differ + row.beyond_chance, tested + 1
        out[row.model] = (differ, tested)
    return out


def to_array(rows: list[Fig13Row]) -> np.ndarray:
    """The rows as a `FIG13_DTYPE` array (for the session file)."""
    out = np.zeros(len(rows), dtype=FIG13_DTYPE)
    for i, row in enumerate(rows):
        values = asdict(row)
        values["model"] = row.model.encode("utf-8")
        out[i] = tuple(values[name] for name in FIG13_DTYPE.names)
    return out
