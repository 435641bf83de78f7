"""Analysis against experiment: the paired test of case-by-case agreement and the equivalence of two rates.

Analysis and experiment rate the *same* cases (one body on the plate in one run), so their outcomes come in pairs.
Two questions, two tests:

- **Do they disagree case by case more one way than the other?** :func:`mcnemar_exact`: McNemar's exact test on
  the discordant pairs (McNemar 1947; the exact, conditional form: under "no systematic disagreement" each of the
  ``b + c`` discordant pairs falls either way with probability ½, two-sided p = min(1, 2·P(X ≤ min(b, c))),
  X ~ Binomial(b + c, ½)). Concordant pairs carry no information about the difference and do not enter.
- **Are the two rates the same within a margin?** The paper's claim ("a maximum of 5 % difference … for a given
  angle and specific body") is an *equivalence*: a test of "the rates differ by less than δ" must put the burden
  of proof on equivalence, which a test of "they are equal" (a large p-value) does not — with three cases nothing
  is "beyond chance" and nothing is shown either. :func:`equivalence` runs the two one-sided tests (TOST,
  Schuirmann 1987) of H0: p₁ − p₂ ≤ −δ and H0: p₁ − p₂ ≥ +δ with the Miettinen–Nurminen score statistic
  (Miettinen & Nurminen 1985; the restricted maximum-likelihood rates of Farrington & Manning 1990 in closed form,
  variance × N/(N − 1)); each at level α, so that TOST at α is the (1 − 2α) score interval lying inside (−δ, δ).
  The verdict is one of three (:class:`Verdict`): **equivalent** (both nulls rejected: the 90 % interval of the
  difference lies inside ±δ), **different** (the difference is beyond the margin: the one-sided test of
  "within δ on the observed side" rejected, the 90 % interval lies outside ±δ), or **not resolved** — with the
  number of cases at which the same observed rates would resolve it (:func:`cases_to_resolve`).

The rates compared are the controlled-overturning rates as Fig. 13 draws them: for the analysis among the cases it
overturns, for the experiment among those the specimens overturn. Those two sets are not the same cases, so the
equivalence test takes them as two binomial samples; because the two sides rate the same records, their rates are
positively correlated, the independent-samples variance is then the larger one, and the test is conservative: it
calls "equivalent" or "different" only where a paired variance would too (it leaves more cases "not resolved").

:func:`equivalence_power` is the exact power of that test (the sum over every pair of binomial outcomes of its
probability times whether TOST declares equivalence), and :func:`cases_for_power` the smallest number of cases per
side that reaches a power: what a campaign needs before it runs (``rig plan``).

Rates and margins are fractions (0.05 = 5 percentage points); differences are rate₁ − rate₂ (analysis − experiment).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq
from scipy.stats import binom, binomtest, norm

MARGIN = 0.05
"""The equivalence margin δ [fraction]: the paper's "maximum of 5 % difference"."""

ALPHA = 0.05
"""Level of each one-sided test of TOST (the 90 % interval of the difference)."""

EQUIVALENT = "equivalent"
DIFFERENT = "different"
NOT_RESOLVED = "not resolved"
UNDEFINED = "undefined"
"""The verdicts (:class:`Verdict`); ``undefined`` where a rate is (nothing overturned on one side)."""

MAX_CASES = 1_000_000
"""Searches for a number of cases stop here (None beyond it)."""


def mcnemar_exact(b: int, c: int) -> float:
    """Two-sided p-value of McNemar's exact test from the discordant pair counts ``b`` and ``c`` (module
    docstring); 1 when there is no discordant pair. ValueError for negative counts."""
    if b < 0 or c < 0:
        raise ValueError(f"mcnemar_exact: expected counts ≥ 0, got b={b}, c={c}")
    if b + c == 0:
        return 1.0
    return float(binomtest(min(b, c), b + c, 0.5, alternative="two-sided").pvalue)


def _restricted_rates(p1: np.ndarray, p2: np.ndarray, n1: float, n2: float, delta: float
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The maximum-likelihood rates (p̃₁, p̃₂) under p₁ − p₂ = ``delta`` (Farrington & Manning 1990, the closed
    form of the cubic's root in (0, 1))."""
    theta = n2 / n1
    a = 1.0 + theta
    b = -(1.0 + theta + p1 + theta * p2 + delta * (theta + 2.0))
    c = delta * delta + delta * (2.0 * p1 + theta + 1.0) + p1 + theta * p2
    d = -p1 * delta * (1.0 + delta)
    v = b**3 / (3.0 * a) ** 3 - b * c / (6.0 * a * a) + d / (2.0 * a)
    u = np.where(v >= 0, 1.0, -1.0) * np.sqrt(np.maximum(b * b / (3.0 * a) ** 2 - c / (3.0 * a), 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(u == 0, 0.0, v / np.where(u == 0, 1.0, u) ** 3)
    w = (math.pi + np.arccos(np.clip(ratio, -1.0, 1.0))) / 3.0
    q1 = np.clip(2.0 * u * np.cos(w) - b / (3.0 * a), 0.0, 1.0)
    return q1, np.clip(q1 - delta, 0.0, 1.0)


def score_statistic(k1: float | np.ndarray, n1: float, k2: float | np.ndarray, n2: float, delta: float
                    ) -> np.ndarray:
    """The Miettinen–Nurminen score statistic z of H0: p₁ − p₂ = ``delta`` from ``k1`` of ``n1`` and ``k2`` of
    ``n2`` (counts may be arrays, or fractional for planning): positive when the observed difference exceeds
    ``delta``. Infinite where the restricted variance is 0 and the difference is not ``delta``."""
    k1, k2 = np.asarray(k1, dtype=float), np.asarray(k2, dtype=float)
    p1, p2 = k1 / n1, k2 / n2
    q1, q2 = _restricted_rates(p1, p2, n1, n2, delta)
    variance = (q1 * (1.0 - q1) / n1 + q2 * (1.0 - q2) / n2) * (n1 + n2) / (n1 + n2 - 1.0)
    excess = p1 - p2 - delta
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(variance > 0, excess / np.sqrt(np.where(variance > 0, variance, 1.0)),
                     np.where(excess > 0, np.inf, np.where(excess < 0, -np.inf, 0.0)))
    return z


@dataclass(frozen=True)
class Verdict:
    """The equivalence of two rates within ``margin`` (module docstring).

    ``verdict``: ``equivalent``, ``different``, ``not resolved`` or ``undefined``; ``difference``: rate₁ − rate₂;
    ``low``/``high``: its (1 − 2α) score interval; ``p_equivalent``: the TOST p-value (the larger of the two
    one-sided p-values; below α: equivalent); ``p_different``: the one-sided p-value of "within the margin on the
    observed side" (below α: different); ``cases``: the cases it was judged on; ``cases_to_resolve``: with
    ``not resolved``, the cases at which the same rates would resolve it (None: never, e.g. a difference exactly
    at the margin, or more than :data:`MAX_CASES`).
    """

    verdict: str
    difference: float
    low: float
    high: float
    p_equivalent: float
    p_different: float
    margin: float
    cases: int = 0
    cases_to_resolve: int | None = None


def _one_sided(k1: float, n1: float, k2: float, n2: float, margin: float) -> tuple[float, float, float]:
    """(p of H0 d ≤ −δ, p of H0 d ≥ +δ, p of "within δ on the observed side")."""
    z_low = float(score_statistic(k1, n1, k2, n2, -margin))
    z_high = float(score_statistic(k1, n1, k2, n2, margin))
    p_low, p_high = float(norm.sf(z_low)), float(norm.cdf(z_high))
    d = k1 / n1 - k2 / n2
    p_beyond = float(norm.sf(z_high)) if d >= 0 else float(norm.cdf(z_low))
    return p_low, p_high, p_beyond


def _classify(p_low: float, p_high: float, p_beyond: float, alpha: float) -> str:
    if max(p_low, p_high) < alpha:
        return EQUIVALENT
    if p_beyond < alpha:
        return DIFFERENT
    return NOT_RESOLVED


def score_interval(k1: float, n1: int, k2: float, n2: int, confidence: float = 1.0 - 2.0 * ALPHA
                   ) -> tuple[float, float]:
    """The Miettinen–Nurminen score interval of p₁ − p₂ at ``confidence`` (two-sided), by inverting
    :func:`score_statistic`; (NaN, NaN) when either ``n`` is 0."""
    if n1 == 0 or n2 == 0:
        return math.nan, math.nan
    z = float(norm.ppf(0.5 + confidence / 2.0))
    d = k1 / n1 - k2 / n2
    eps = 1e-12

    def f(delta: float, target: float) -> float:
        return float(score_statistic(k1, n1, k2, n2, delta)) - target

    low = -1.0 if f(-1.0 + eps, z) <= 0 else brentq(f, -1.0 + eps, d, args=(z,), xtol=1e-12)
    high = 1.0 if f(1.0 - eps, -z) >= 0 else brentq(f, d, 1.0 - eps, args=(-z,), xtol=1e-12)
    return float(low), float(high)


def equivalence(k1: float, n1: int, k2: float, n2: int, margin: float = MARGIN, alpha: float = ALPHA,
                cases: int | None = None, overturn_fractions: tuple[float, float] | None = None) -> Verdict:
    """TOST of rate ``k1``/``n1`` against ``k2``/``n2`` within ``margin`` (module docstring); the counts may be
    fractional (a rate times a number of records).

    ``cases``: the cases the rates were counted among (default ``max(n1, n2)``); ``overturn_fractions``: the
    fraction of those cases that enters each rate (default ``n1/cases``, ``n2/cases``) — a search for the cases
    that would resolve a ``not resolved`` verdict scales both counts by them. ValueError for bad counts or a margin
    outside (0, 1).
    """
    for k, n in ((k1, n1), (k2, n2)):
        if not 0 <= k <= n:
            raise ValueError(f"equivalence: expected 0 ≤ k ≤ n, got k={k}, n={n}")
    if not 0.0 < margin < 1.0:
        raise ValueError(f"equivalence: margin must be in (0, 1) (a fraction: 0.05 = 5 points), got {margin}")
    cases = max(n1, n2) if cases is None else cases
    if n1 == 0 or n2 == 0:
        return Verdict(UNDEFINED, math.nan, math.nan, math.nan, math.nan, math.nan, margin, cases)
    p_low, p_high, p_beyond = _one_sided(k1, n1, k2, n2, margin)
    verdict = _classify(p_low, p_high, p_beyond, alpha)
    low, high = score_interval(k1, n1, k2, n2, 1.0 - 2.0 * alpha)
    needed = None
    if verdict == NOT_RESOLVED:
        f1, f2 = overturn_fractions or (n1 / cases, n2 / cases)
        needed = cases_to_resolve(k1 / n1, f1, k2 / n2, f2, margin, alpha)
    return Verdict(verdict, k1 / n1 - k2 / n2, low, high, max(p_low, p_high), p_beyond, margin, cases, needed)


def cases_to_resolve(p1: float, f1: float, p2: float, f2: float, margin: float = MARGIN, alpha: float = ALPHA
                     ) -> int | None:
    """The smallest number of cases N at which rates ``p1`` and ``p2``, counted among the fractions ``f1`` and
    ``f2`` of the cases (overturns per case on each side), would be called equivalent or different by
    :func:`equivalence` (counts p·f·N, fractional); None if no N up to :data:`MAX_CASES` does (a difference at
    the margin)."""
    if f1 <= 0 or f2 <= 0:
        return None

    def resolved(n: float) -> bool:
        n1, n2 = f1 * n, f2 * n
        if n1 + n2 <= 1.0:
            return False
        return _classify(*_one_sided(p1 * n1, n1, p2 * n2, n2, margin), alpha) != NOT_RESOLVED

    high = 2
    while not resolved(high):
        high *= 2
        if high > MAX_CASES:
            return None
    return _first_true(resolved, high // 2, high)  # the statistic grows with N at fixed rates


def _likely_counts(n: int, p: float) -> np.ndarray:
    """The counts 0…n of a Binomial(n, p) outside which the probability is below 1e-15 (left out of sums)."""
    low, high = binom.ppf(1e-15, n, p), binom.isf(1e-15, n, p)
    return np.arange(max(0, int(low) - 1), min(n, int(high) + 1) + 1, dtype=float)


def equivalence_power(p1: float, n1: int, p2: float, n2: int, margin: float = MARGIN, alpha: float = ALPHA
                      ) -> float:
    """The probability that TOST (:func:`equivalence`) calls rates of ``n1`` and ``n2`` binomial trials with true
    rates ``p1`` and ``p2`` equivalent within ``margin`` — exact: Σ P(k₁) P(k₂) over every (k₁, k₂) it accepts
    (counts of probability below 1e-15 left out)."""
    if n1 < 1 or n2 < 1:
        return 0.0
    k1 = _likely_counts(n1, p1)[:, None]
    k2 = _likely_counts(n2, p2)[None, :]
    z_low = score_statistic(k1, n1, k2, n2, -margin)
    z_high = score_statistic(k1, n1, k2, n2, margin)
    accept = (norm.sf(z_low) < alpha) & (norm.cdf(z_high) < alpha)
    weights = binom.pmf(k1, n1, p1) * binom.pmf(k2, n2, p2)
    return float(np.sum(weights[accept]))


def cases_for_power(p1: float, p2: float | None = None, margin: float = MARGIN, power: float = 0.8,
                    alpha: float = ALPHA, limit: int = 5000) -> int | None:
    """The smallest n (the same on both sides) at which :func:`equivalence_power` reaches ``power`` for true rates
    ``p1`` and ``p2`` (default: the same rate, the hope of a campaign that its analysis is right); None when no
    n up to ``limit`` does (|p1 − p2| ≥ margin never becomes equivalent). The power of an exact test is not
    monotone in n (it saw-tooths by a few percent): this is an n that reaches it where n − 1 does not, found by
    bisection from a normal approximation, not a scan from 1."""
    p2 = p1 if p2 is None else p2
    if abs(p1 - p2) >= margin:
        return None

    def enough(n: int) -> bool:
        return equivalence_power(p1, n, p2, n, margin, alpha) >= power

    # a normal-approximation start (Chow, Shao & Wang 2008, §4.2.2), then doubling and bisection to an n that
    # reaches the power where n − 1 does not
    spread = p1 * (1 - p1) + p2 * (1 - p2)
    z = norm.ppf(1 - alpha) + norm.ppf(1 - (1 - power) / (2 if p1 == p2 else 1))
    high = min(limit, max(2, int(z * z * max(spread, 1e-3) / (margin - abs(p1 - p2)) ** 2)))
    low = 1
    while not enough(high):
        if high >= limit:
            return None
        low, high = high, min(limit, 2 * high)
    if high > 2 and enough(high // 2):
        high = high // 2
        while high > 2 and enough(high // 2):
            high //= 2
        low = high // 2
    return _first_true(enough, low, high)


def _first_true(holds: Callable[[int], bool], low: int, high: int) -> int:
    """By bisection, an n in (``low``, ``high``] where ``holds(n)`` and not ``holds(n − 1)``, given that ``holds``
    fails at ``low`` and holds at ``high`` (the first such n when ``holds`` is monotone)."""
    while high - low > 1:
        mid = (low + high) // 2
        if holds(mid):
            high = mid
        else:
            low = mid
    return high
