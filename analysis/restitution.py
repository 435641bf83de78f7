"""A body's coefficient of restitution identified from its measured rocking angle.

The coefficient of restitution e of a rocking body is the ratio of its angular velocities just after and just
before an impact, e = θ'⁺/θ'⁻ (Housner 1963; docs/validation.md V4, Housner's rigid-block value 1 − 1.5 sin²α).
:func:`impact_ratios` reads it at every impact of a sampled angle θ(t) [rad] (the body's rotation relative to
the plate, any sign convention): an impact is a change of sign of θ, the pivot moving from one base corner to
the other. The angular velocity on each side is the slope at the crossing of a quadratic fitted to the samples
between ``gap`` and ``window`` seconds before (after) it — the angle's own curvature and a constant plate
acceleration are absorbed by the quadratic; the samples within ``gap`` of the crossing are left out because a
real (or soft-contact) impact lasts a few milliseconds. The plate may be moving: an impact is instantaneous next
to the motion between impacts, so the ratio holds during shaking as in free rocking.

An impact is used only when it is clean: the rate before it at least ``min_rate`` [rad/s] (a resting body's
noise has no impacts), enough samples on both sides, each side's samples on one smooth arc (within
:data:`MAX_RESIDUAL` of its quadratic: a body put back upright after a fall jumps, it does not rock), no other
crossing within ``window`` of it (chatter), and the body still rocking the same way after it (the ratio within
(0, ``max_ratio``]).

:func:`fit_restitution` combines the ratios of one body (from any number of runs): the median (robust to the
odd impact disturbed by a neighbour or a jolt), with a 95 % interval of the median from the order statistics
(distribution-free, binomial). Units: seconds, radians, radians per second.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.stats import binom

from analysis.errors import AnalysisInputError

WINDOW = 0.04
"""Seconds of samples on each side of an impact that give the angular velocity there."""

GAP = 0.01
"""Seconds next to an impact left out of the fits (a contact's impact lasts a few milliseconds)."""

MIN_RATE = 0.05
"""Smallest angular velocity before an impact that counts [rad/s] (a 0.1 × 0.5 m block rocking 0.005 rad has
about 0.12 rad/s at impact)."""

MAX_RATIO = 1.2
"""Largest ratio kept: above 1 only by measurement error (an impact takes energy out)."""

MAX_RESIDUAL = 2e-3
"""Largest distance [rad] of a side's samples from its quadratic (a rocking arc fits within 1e-4 rad)."""

MIN_SAMPLES = 3
"""Samples needed on each side of an impact for its quadratic."""


@dataclass(frozen=True)
class Impact:
    """One impact: time [s], angular velocity just before and just after [rad/s], their ratio."""

    t: float
    rate_before: float
    rate_after: float

    @property
    def ratio(self) -> float:
        return self.rate_after / self.rate_before


@dataclass(frozen=True)
class RestitutionFit:
    """A body's restitution from ``impacts`` clean impacts: the median ratio ``value`` and its 95 % interval
    [``low``, ``high``] (NaN without impacts)."""

    value: float
    low: float
    high: float
    impacts: int

    def to_dict(self) -> dict[str, float | int]:
        return {"value": self.value, "low": self.low, "high": self.high, "impacts": self.impacts}


def impact_ratios(t: ArrayLike, theta: ArrayLike, *, window: float = WINDOW, gap: float = GAP,
                  min_rate: float = MIN_RATE, max_ratio: float = MAX_RATIO) -> list[Impact]:
    """Every clean impact in the angle ``theta`` [rad] sampled at increasing times ``t`` [s] (module docstring).

    Gaps in the samples (a lost batch) are allowed: an impact whose crossing falls in a gap longer than ``gap``,
    or whose windows lack :data:`MIN_SAMPLES` samples on a side, is skipped. Raises `AnalysisInputError` for
    mismatched, non-finite or unordered input."""
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    theta = np.asarray(theta, dtype=np.float64).reshape(-1)
    if t.shape != theta.shape:
        raise AnalysisInputError(f"t has {t.size} samples, theta has {theta.size}: they must match")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(theta))):
        raise AnalysisInputError("t and theta must be finite")
    if t.size > 1 and np.any(np.diff(t) <= 0):
        raise AnalysisInputError("t must increase")
    if not 0 <= gap < window:
        raise AnalysisInputError(f"gap {gap} s and window {window} s: need 0 <= gap < window")
    sign = np.sign(theta)
    crossings = np.flatnonzero(sign[:-1] * sign[1:] < 0)
    at = t[crossings] - theta[crossings] * (t[crossings + 1] - t[crossings]) / (theta[crossings + 1]
                                                                                - theta[crossings])
    impacts = []
    for k, tc in enumerate(at):
        if t[crossings[k] + 1] - t[crossings[k]] > gap:  # a lost batch hides when it happened
            continue
        if (k > 0 and tc - at[k - 1] < window) or (k + 1 < len(at) and at[k + 1] - tc < window):
            continue
        before = _slope(t, theta, tc, tc - window, tc - gap)
        after = _slope(t, theta, tc, tc + gap, tc + window)
        if before is None or after is None or abs(before) < min_rate:
            continue
        impact = Impact(float(tc), before, after)
        if 0.0 < impact.ratio <= max_ratio:
            impacts.append(impact)
    return impacts


def _slope(t: np.ndarray, theta: np.ndarray, tc: float, start: float, end: float) -> float | None:
    """Slope at ``tc`` of the quadratic through the samples in [start, end] (None: too few, or not on one arc)."""
    lo, hi = np.searchsorted(t, min(start, end), "left"), np.searchsorted(t, max(start, end), "right")
    if hi - lo < MIN_SAMPLES:
        return None
    coefficients = np.polynomial.polynomial.polyfit(t[lo:hi] - tc, theta[lo:hi], 2)
    residual = theta[lo:hi] - np.polynomial.polynomial.polyval(t[lo:hi] - tc, coefficients)
    if np.max(np.abs(residual)) > MAX_RESIDUAL:
        return None
    return float(coefficients[1])


def fit_restitution(impacts: list[Impact]) -> RestitutionFit:
    """The median of the impacts' ratios and its 95 % distribution-free interval (module docstring)."""
    ratios = np.sort([impact.ratio for impact in impacts])
    n = len(ratios)
    if n == 0:
        return RestitutionFit(math.nan, math.nan, math.nan, 0)
    low_rank = int(binom.ppf(0.025, n, 0.5))  # P(fewer than low_rank + 1 ratios below the median) ≈ 2.5 %
    low = ratios[max(low_rank - 1, 0)] if low_rank > 0 else ratios[0]
    high = ratios[min(n - low_rank, n - 1)]
    return RestitutionFit(float(np.median(ratios)), float(low), float(high), n)
