"""Rates from counts: the Wilson score interval of a proportion and an exact test of two proportions.

A controlled-overturning rate (COR) is a proportion k/n — k overturns towards the low side among n overturns — and
with the few cases of a shake-table campaign (three runs per body and angle in the quick sequence, about 25 in the
paper's) its sampling error is tens of percentage points. These functions say how far a rate can be trusted:

- :func:`wilson_interval`: the Wilson score interval (Wilson 1927; Agresti & Coull 1998 recommend it over the
  normal "Wald" interval, which collapses to a point at k = 0 or k = n and undercovers for small n);
- :func:`exact_two_proportions`: Fisher's exact test of "the two rates are equal" on the 2×2 table of counts
  (``scipy.stats.fisher_exact``, two-sided). Analysis and experiment rate the same cases, so their outcomes are
  positively correlated; a test that treats them as independent samples is then conservative (it calls a
  difference "beyond chance" less often than a paired test would), which is the safe side for a claim that the
  analysis disagrees with the experiment.
"""

from __future__ import annotations

import math

from scipy.stats import fisher_exact, norm

CONFIDENCE = 0.95
"""The confidence level of the intervals reported."""

SIGNIFICANCE = 0.05
"""A difference with a p-value below this is "beyond chance"."""


def wilson_interval(k: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """The Wilson score interval (low, high) of the proportion ``k``/``n`` at ``confidence``; (NaN, NaN) when
    ``n`` is 0 (no rate). ValueError unless 0 ≤ k ≤ n and 0 < confidence < 1."""
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


def exact_two_proportions(k1: int, n1: int, k2: int, n2: int) -> float:
    """Two-sided p-value of Fisher's exact test that ``k1``/``n1`` and ``k2``/``n2`` come from the same rate; NaN
    when either ``n`` is 0 (a rate is undefined)."""
    for k, n in ((k1, n1), (k2, n2)):
        if not (0 <= k <= n):
            raise ValueError(f"exact_two_proportions: expected 0 ≤ k ≤ n, got k={k}, n={n}")
    if n1 == 0 or n2 == 0:
        return math.nan
    return float(fisher_exact([[k1, n1 - k1], [k2, n2 - k2]], alternative="two-sided").pvalue)
