"""Analysis against experiment (``analysis.agreement``) against independent truths: statsmodels' McNemar
(``mcnemar(exact=True)``); the restricted rates of the score test against a numerical maximum of the constrained
likelihood; statsmodels' Miettinen–Nurminen score test, interval and TOST where its restricted rates are right;
a Monte Carlo of a brute-force TOST for the exact power; the closed forms where there are some.

statsmodels 0.15's score test for a difference ≠ 0 puts a count where a sample size belongs in its cubic
(statsmodels issue #10269, open): its restricted rates do not maximise the likelihood (checked below) unless the
second sample is all successes (``count2 == nobs2``, where the two coincide). It is compared there only."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
from scipy.optimize import minimize_scalar
from scipy.stats import norm
from statsmodels.stats.contingency_tables import mcnemar
from statsmodels.stats.proportion import (
    confint_proportions_2indep,
    score_test_proportions_2indep,
    tost_proportions_2indep,
)

from analysis.agreement import (
    ALPHA,
    DIFFERENT,
    EQUIVALENT,
    NOT_RESOLVED,
    UNDEFINED,
    _restricted_rates,
    cases_for_power,
    cases_to_resolve,
    equivalence,
    equivalence_power,
    mcnemar_exact,
    score_interval,
    score_statistic,
)


@pytest.mark.parametrize(("b", "c"), [(0, 1), (0, 5), (3, 9), (8, 8), (1, 12), (20, 31), (0, 0)])
def test_mcnemar_exact_matches_statsmodels(b: int, c: int) -> None:
    table = [[10, b], [c, 7]]  # the concordant cells do not enter
    expected = mcnemar(table, exact=True).pvalue
    assert mcnemar_exact(b, c) == pytest.approx(min(1.0, expected), rel=1e-12)
    assert mcnemar_exact(c, b) == mcnemar_exact(b, c)


def test_mcnemar_closed_form_all_discordant_one_way() -> None:
    for n in (1, 4, 8, 16):  # b = 0, c = n: p = 2 · ½ⁿ (capped at 1)
        assert mcnemar_exact(0, n) == pytest.approx(min(1.0, 2 * 0.5**n))
    with pytest.raises(ValueError, match="≥ 0"):
        mcnemar_exact(-1, 2)


COUNTS = [(16, 16, 22, 24), (24, 25, 23, 25), (20, 24, 22, 24), (3, 3, 2, 3), (45, 50, 40, 48), (90, 100, 91, 100),
          (50, 100, 52, 100), (12, 30, 20, 33), (0, 10, 1, 12), (30, 30, 30, 30)]
ALL_SECOND = [(22, 24, 16, 16), (23, 25, 25, 25), (2, 3, 3, 3), (40, 48, 50, 50), (91, 100, 100, 100), (0, 10, 12, 12),
              (30, 30, 30, 30)]
"""Counts whose second sample is all successes: statsmodels' cubic is right there."""


def _constrained_maximum(k1: float, n1: float, k2: float, n2: float, delta: float) -> tuple[float, float]:
    """The rates maximising the binomial likelihood under p1 − p2 = delta, numerically."""
    def minus_log_likelihood(p2: float) -> float:
        p1 = p2 + delta
        return -(k1 * math.log(p1) + (n1 - k1) * math.log1p(-p1) + k2 * math.log(p2) + (n2 - k2) * math.log1p(-p2))

    low, high = max(0.0, -delta) + 1e-12, min(1.0, 1.0 - delta) - 1e-12
    best = minimize_scalar(minus_log_likelihood, bounds=(low, high), method="bounded", options={"xatol": 1e-12})
    return best.x + delta, best.x


@pytest.mark.parametrize("counts", COUNTS)
@pytest.mark.parametrize("delta", [-0.2, -0.05, 0.05, 0.2])
def test_restricted_rates_maximise_the_constrained_likelihood(counts: tuple[int, int, int, int], delta: float) -> None:
    k1, n1, k2, n2 = counts
    q1, q2 = _restricted_rates(np.array(k1 / n1), np.array(k2 / n2), n1, n2, delta)
    expected = _constrained_maximum(k1, n1, k2, n2, delta)
    assert (float(q1), float(q2)) == pytest.approx(expected, abs=1e-6)


@pytest.mark.parametrize("counts", COUNTS)
def test_score_statistic_of_equal_rates_matches_statsmodels(counts: tuple[int, int, int, int]) -> None:
    k1, n1, k2, n2 = counts
    expected = score_test_proportions_2indep(k1, n1, k2, n2, value=0.0, compare="diff", correction=True).statistic
    ours = float(score_statistic(k1, n1, k2, n2, 0.0))
    assert ours == pytest.approx(expected, rel=1e-9, abs=1e-12) if math.isfinite(expected) else ours == 0.0


@pytest.mark.parametrize("counts", ALL_SECOND)
@pytest.mark.parametrize("delta", [-0.05, 0.05, 0.2])
def test_score_statistic_matches_statsmodels(counts: tuple[int, int, int, int], delta: float) -> None:
    k1, n1, k2, n2 = counts
    expected = score_test_proportions_2indep(k1, n1, k2, n2, value=delta, compare="diff", correction=True)
    assert float(score_statistic(k1, n1, k2, n2, delta)) == pytest.approx(expected.statistic, rel=1e-7)


def test_statsmodels_restricted_rates_are_off_elsewhere() -> None:
    """Why the comparisons above stop at ``count2 == nobs2``: at (16/16, 22/24) and δ = −0.05 statsmodels' null
    rates give a lower likelihood than ours, which are the numerical maximum."""
    result = score_test_proportions_2indep(16, 16, 22, 24, value=-0.05, compare="diff")
    q1, _ = _restricted_rates(np.array(1.0), np.array(22 / 24), 16, 24, -0.05)

    def log_likelihood(p1: float) -> float:
        p2 = p1 + 0.05
        return 16 * math.log(p1) + 22 * math.log(p2) + 2 * math.log1p(-p2)

    assert log_likelihood(float(q1)) > log_likelihood(float(result.prop1_null)) + 1e-4


@pytest.mark.parametrize("counts", [(40, 48, 50, 50), (91, 100, 100, 100), (45, 50, 60, 60), (18, 24, 30, 30)])
def test_score_interval_matches_statsmodels(counts: tuple[int, int, int, int]) -> None:
    """(statsmodels' root search fails where a rate is 0 or 1 on the first side: compared where it does not.)"""
    k1, n1, k2, n2 = counts
    for confidence in (0.90, 0.95):
        low, high = confint_proportions_2indep(k1, n1, k2, n2, method="score", compare="diff",
                                               alpha=1 - confidence, correction=True)
        assert score_interval(k1, n1, k2, n2, confidence) == pytest.approx((low, high), abs=2e-6)


@pytest.mark.parametrize("counts", ALL_SECOND)
@pytest.mark.parametrize("margin", [0.05, 0.10, 0.20])
def test_tost_p_value_matches_statsmodels(counts: tuple[int, int, int, int], margin: float) -> None:
    k1, n1, k2, n2 = counts
    expected = tost_proportions_2indep(k1, n1, k2, n2, -margin, margin, method="score", compare="diff",
                                       correction=True)
    verdict = equivalence(k1, n1, k2, n2, margin)
    assert verdict.p_equivalent == pytest.approx(expected.pvalue, rel=1e-6, abs=1e-12)
    assert (verdict.verdict == EQUIVALENT) == (expected.pvalue < 0.05)


@pytest.mark.parametrize("counts", COUNTS)
@pytest.mark.parametrize("margin", [0.05, 0.10, 0.20])
def test_verdict_is_the_90_percent_interval_against_the_margin(counts: tuple[int, int, int, int], margin: float
                                                                ) -> None:
    """TOST at 5 % ⇔ the 90 % score interval inside ±margin; "different" ⇔ that interval outside it."""
    k1, n1, k2, n2 = counts
    verdict = equivalence(k1, n1, k2, n2, margin)
    low, high = score_interval(k1, n1, k2, n2, 0.90)
    assert (verdict.verdict == EQUIVALENT) == (-margin < low and high < margin)
    assert (verdict.verdict == DIFFERENT) == (low > margin or high < -margin)


def _brute_force_accepts(k1: int, n1: int, k2: int, n2: int, margin: float) -> bool:
    """TOST written out: the numerical constrained maximum at ±margin, the corrected score variance, both
    one-sided p-values below 5 %."""
    p1, p2, total = k1 / n1, k2 / n2, n1 + n2
    for delta, side in ((-margin, norm.sf), (margin, norm.cdf)):
        q1, q2 = _constrained_maximum(k1, n1, k2, n2, delta)
        variance = (q1 * (1 - q1) / n1 + q2 * (1 - q2) / n2) * total / (total - 1)
        if side((p1 - p2 - delta) / math.sqrt(variance)) >= ALPHA:
            return False
    return True


def test_the_issue_s_case_is_not_resolved_and_says_how_many_would() -> None:
    """Issue 24's re-run at 4°: analysis 16 of 16 overturns low, experiment 22 of 24 (25 runs)."""
    verdict = equivalence(16, 16, 22, 24, 0.05, cases=25)
    assert verdict.verdict == NOT_RESOLVED and verdict.difference == pytest.approx(16 / 16 - 22 / 24)
    n = verdict.cases_to_resolve
    assert n is not None and n > 25
    assert verdict.cases == 25
    # at n runs, the same rates (16/25 and 24/25 of the runs overturning) resolve it, at n − 1 not: the analysis's
    # rate is 1 (all successes), so with the samples swapped statsmodels' cubic is right (swapped: −difference)
    for runs, resolved in ((n, True), (n - 1, False)):
        n1, n2 = 16 / 25 * runs, 24 / 25 * runs
        tost = tost_proportions_2indep(22 / 24 * n2, n2, n1, n1, -0.05, 0.05, method="score", compare="diff")
        beyond = score_test_proportions_2indep(22 / 24 * n2, n2, n1, n1, value=-0.05, compare="diff",
                                               alternative="smaller")
        assert (tost.pvalue < 0.05 or beyond.pvalue < 0.05) == resolved, runs


def test_verdicts_at_the_extremes() -> None:
    assert equivalence(250, 250, 249, 250, 0.05).verdict == EQUIVALENT
    assert equivalence(25, 25, 5, 25, 0.05).verdict == DIFFERENT
    assert equivalence(0, 0, 3, 4).verdict == UNDEFINED
    assert cases_to_resolve(0.95, 1.0, 0.90, 1.0, 0.05) is None  # exactly at the margin: never
    with pytest.raises(ValueError, match="margin"):
        equivalence(1, 2, 1, 2, 5.0)


@pytest.mark.parametrize(("p1", "p2", "n"), [(0.95, 0.95, 60), (0.9, 0.92, 150), (0.5, 0.5, 400)])
def test_exact_power_matches_a_monte_carlo_of_a_brute_force_tost(p1: float, p2: float, n: int) -> None:
    exact = equivalence_power(p1, n, p2, n, 0.05)
    rng = np.random.default_rng(7)
    draws = 4000
    k1, k2 = rng.binomial(n, p1, draws), rng.binomial(n, p2, draws)
    accepts = cache(_brute_force_accepts)
    simulated = np.mean([accepts(int(a), n, int(b), n, 0.05) for a, b in zip(k1, k2, strict=True)])
    se = math.sqrt(max(exact * (1 - exact), 1e-4) / draws)
    assert abs(simulated - exact) < 4 * se, (simulated, exact)


def test_cases_for_power_against_the_normal_approximation_and_its_own_power() -> None:
    n = cases_for_power(0.5, margin=0.05, power=0.8)
    # Chow, Shao & Wang (2008) §4.2.2, equal rates: n = (z_{1−α} + z_{1−β/2})² · 2p(1−p) / δ²
    z = norm.ppf(0.95) + norm.ppf(0.9)
    approx = z * z * 2 * 0.25 / 0.05**2
    assert n is not None and abs(n - approx) / approx < 0.03
    assert equivalence_power(0.5, n, 0.5, n, 0.05) >= 0.8 > equivalence_power(0.5, n - 1, 0.5, n - 1, 0.05)
    near_one = cases_for_power(0.99, margin=0.05, power=0.8)
    assert near_one is not None and near_one < n / 10  # rates near 1 vary little: far fewer cases
    assert cases_for_power(0.9, 0.8, margin=0.05) is None  # 10 points apart: never within 5
