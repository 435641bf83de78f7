"""Rates from counts (``analysis.proportions``) against independent truths: scipy's own Wilson interval
(``binomtest(...).proportion_ci(method="wilson")``, a separate implementation), a published worked example, the
closed forms at k = 0 and k = n, and Fisher's test written out as a sum over the hypergeometric distribution."""

from __future__ import annotations

import math

import pytest
from scipy.stats import binomtest, hypergeom

from analysis.proportions import exact_two_proportions, wilson_interval
from rig.analyze.fig13 import Case, beyond_chance, fig13_rows


@pytest.mark.parametrize(("k", "n"), [(0, 1), (1, 1), (0, 3), (1, 3), (2, 3), (3, 3), (7, 25), (24, 25),
                                      (50, 100), (1, 1000)])
def test_wilson_matches_scipy_s_own_implementation(k: int, n: int) -> None:
    ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    assert wilson_interval(k, n) == pytest.approx((ci.low, ci.high), abs=1e-12)


def test_wilson_published_example_and_closed_forms() -> None:
    # Newcombe (1998), Statistics in Medicine 17:857, Table I, example (a): 81/263 → 0.2553–0.3662 (method 3)
    low, high = wilson_interval(81, 263)
    assert (round(low, 4), round(high, 4)) == (0.2553, 0.3662)
    z2 = 1.959963984540054 ** 2
    for n in (1, 3, 25):  # k = 0: (0, z²/(n + z²)); k = n: (n/(n + z²), 1)
        assert wilson_interval(0, n) == pytest.approx((0.0, z2 / (n + z2)))
        assert wilson_interval(n, n) == pytest.approx((n / (n + z2), 1.0))
    assert all(math.isnan(x) for x in wilson_interval(0, 0))
    with pytest.raises(ValueError, match="0 ≤ k ≤ n"):
        wilson_interval(4, 3)


def _fisher_by_hand(k1: int, n1: int, k2: int, n2: int) -> float:
    """Two-sided Fisher: the probability of every table with the same margins no more likely than the observed."""
    total, successes = n1 + n2, k1 + k2
    dist = hypergeom(total, successes, n1)
    observed = dist.pmf(k1)
    return float(sum(dist.pmf(x) for x in range(max(0, successes - n2), min(successes, n1) + 1)
                     if dist.pmf(x) <= observed * (1 + 1e-7)))


@pytest.mark.parametrize("counts", [(3, 3, 2, 3), (3, 3, 0, 3), (10, 10, 2, 10), (20, 25, 5, 25), (0, 4, 4, 4),
                                    (5, 9, 5, 9)])
def test_fisher_exact_against_the_hypergeometric_sum(counts: tuple[int, int, int, int]) -> None:
    assert exact_two_proportions(*counts) == pytest.approx(_fisher_by_hand(*counts), rel=1e-9)


def test_fisher_exact_undefined_without_overturns_and_symmetric() -> None:
    assert math.isnan(exact_two_proportions(0, 0, 2, 3))
    assert exact_two_proportions(3, 3, 0, 3) == exact_two_proportions(0, 3, 3, 3) == pytest.approx(0.1)
    assert exact_two_proportions(2, 5, 4, 7) == pytest.approx(exact_two_proportions(4, 7, 2, 5))


def test_fig13_rows_carry_intervals_and_33_points_from_three_cases_is_within_chance() -> None:
    """The demo's case: three runs of a body at an angle, the analysis 3 of 3 towards the low side, the experiment
    2 of 3 — a 33-point difference that one overturn makes; the exact test does not call it beyond chance,
    whereas 25 of 25 against 5 of 25 is."""
    cases = [Case(4.0, 1, "rocking", 1, observed) for observed in (1, 1, -1)]
    cases += [Case(5.0, 1, "rocking", 1, 1 if i < 5 else -1) for i in range(25)]
    rows = {(r.angle_deg, r.body_id): r for r in fig13_rows(cases)}
    few, many = rows[(4.0, 1)], rows[(5.0, 1)]
    assert few.difference == pytest.approx(1 / 3)
    assert (few.cor_experiment_low, few.cor_experiment_high) == pytest.approx(wilson_interval(2, 3))
    assert not few.beyond_chance and few.p_value == pytest.approx(1.0)
    assert many.beyond_chance and many.p_value < 1e-6
    assert rows[(4.0, 0)].cor_analysis_low == pytest.approx(wilson_interval(3, 3)[0])  # the average: pooled counts
    assert beyond_chance(fig13_rows(cases)) == {"rocking": (1, 2)}
