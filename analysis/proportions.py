"""Rates from counts: the Wilson score interval of a proportion, and the cluster bootstrap of rates whose cases
share records.

A controlled-overturning rate (COR) is a proportion k/n — k overturns towards the low side among n overturns — and
with the few cases of a shake-table campaign (three runs per body and angle in the quick sequence, about 25 in the
paper's) its sampling error is tens of percentage points. These functions say how far a rate can be trusted:

- :func:`wilson_interval`: the Wilson score interval (Wilson 1927; Agresti & Coull 1998 recommend it over the
  normal "Wald" interval, which collapses to a point at k = 0 or k = n and undercovers for small n). It assumes
  independent cases: right for one body at one angle, where every case is a run of a different record.
- :func:`cluster_resamples`, :func:`mean_rate`, :func:`percentile_interval`: the **cluster bootstrap** (Davison &
  Hinkley 1997, §3.8; Field & Welsh 2007): every body of a campaign sees the same records, so the cases of
  different bodies (and the repetitions of a record, and a record played in both polarities) are not independent
  — a record that overturns one body towards the high side tends to do it to the others. Resampling whole records
  (clusters) with replacement keeps that dependence; an interval from pooled counts treats them as independent and
  is too narrow. Seeded (the same session gives the same interval).
- :func:`degenerate`: whether the resamples hold a single value (every record gave the same outcome), where the
  percentile interval would be a point however few the records.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import norm

CONFIDENCE = 0.95
"""The confidence level of the intervals reported."""

BOOTSTRAP_DRAWS = 4000
"""Resamples of the cluster bootstrap."""

BOOTSTRAP_SEED = 20260101
"""The bootstrap's default seed (a fixed one: the same cases give the same interval)."""

MIN_BOOTSTRAP_RECORDS = 10
"""Below this many records the percentile bootstrap is too narrow (it resamples from the few records seen; with
three, a difference takes a handful of values): callers count each record once instead."""


def wilson_interval(k: float, n: float, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """The Wilson score interval (low, high) of the proportion ``k``/``n`` at ``confidence``; (NaN, NaN) when
    ``n`` is 0 (no rate). ``k`` may be fractional (a rate times a number of records). ValueError unless
    0 ≤ k ≤ n and 0 < confidence < 1."""
    if not (0 <= k <= n):
        raise ValueError(f"wilson_interval: expected 0 ≤ k ≤ n, got k={k}, n={n}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"wilson_interval: confidence must be in (0, 1), got {confidence}")
    if n == 0:
        return math.nan, math.nan
    z = float(norm.ppf(0.5 + confidence / 2.0))
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return max(0.0, centre - half), min(1.0, centre + half)


def cluster_resamples(clusters: int, draws: int = BOOTSTRAP_DRAWS, seed: int = BOOTSTRAP_SEED) -> np.ndarray:
    """(draws, clusters) multiplicities: in each resample, how often each of ``clusters`` records was drawn
    (``clusters`` draws with replacement, so every row sums to ``clusters``)."""
    if clusters < 1 or draws < 1:
        raise ValueError(f"cluster_resamples: expected ≥ 1 cluster and ≥ 1 draw, got {clusters}, {draws}")
    rng = np.random.default_rng(seed)
    return rng.multinomial(clusters, np.full(clusters, 1.0 / clusters), size=draws)


def mean_rate(towards_low: np.ndarray, overturned: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """The mean over groups (bodies) of each group's rate towards_low / overturned, per resample.

    ``towards_low``, ``overturned``: (groups, clusters) counts of each group's cases in each cluster; ``weights``:
    (draws, clusters) multiplicities (`cluster_resamples`; a row of ones gives the observed value). A group
    without an overturn in a resample is left out of that resample's mean (as the average row leaves out a body
    that did not overturn); NaN where no group has one.
    """
    low = weights @ np.asarray(towards_low, dtype=float).T      # (draws, groups)
    over = weights @ np.asarray(overturned, dtype=float).T
    with np.errstate(invalid="ignore", divide="ignore"):
        rates = np.where(over > 0, low / np.where(over > 0, over, 1.0), np.nan)
    defined = np.isfinite(rates)
    count = defined.sum(axis=1)
    total = np.where(defined, rates, 0.0).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.where(count > 0, count, 1), np.nan)


def percentile_interval(samples: np.ndarray, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """The percentile interval (low, high) of the defined ``samples`` at ``confidence``; (NaN, NaN) if none."""
    finite = np.asarray(samples, dtype=float)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return math.nan, math.nan
    tail = 50.0 * (1.0 - confidence)
    low, high = np.percentile(finite, [tail, 100.0 - tail])
    return float(low), float(high)


def degenerate(samples: np.ndarray) -> bool:
    """Whether the resamples hold fewer than two distinct defined values: every record gave the same outcome, and
    the percentile interval would be a point however few the records."""
    finite = np.asarray(samples, dtype=float)
    finite = finite[np.isfinite(finite)]
    return finite.size == 0 or bool(np.ptp(finite) == 0.0)
