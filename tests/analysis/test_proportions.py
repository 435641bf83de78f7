"""Rates from counts (``analysis.proportions``) against independent truths: scipy's own Wilson interval
(``binomtest(...).proportion_ci(method="wilson")``, a separate implementation), a published worked example, the
closed forms at k = 0 and k = n; the cluster bootstrap against ``scipy.stats.bootstrap`` on the records' counts
and against what clustering must do (records shared by identical bodies give no narrower interval than one body);
and the Fig. 13 rows built from them."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import binomtest, bootstrap

from analysis.agreement import equivalence, mcnemar_exact
from analysis.proportions import (
    cluster_resamples,
    mean_rate,
    percentile_interval,
    wilson_interval,
)
from rig.analyze.fig13 import Case, fig13_rows, verdict_counts


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


def test_cluster_resamples_draw_every_record_count_times_and_are_seeded() -> None:
    weights = cluster_resamples(25, draws=1000, seed=3)
    assert weights.shape == (1000, 25) and (weights.sum(axis=1) == 25).all()
    assert np.array_equal(weights, cluster_resamples(25, draws=1000, seed=3))
    assert not np.array_equal(weights, cluster_resamples(25, draws=1000, seed=4))
    assert abs(weights.mean() - 1.0) < 0.01  # each record drawn once per resample on average


def test_cluster_bootstrap_matches_scipy_s_bootstrap_of_the_records() -> None:
    """One body, 40 records each played 3 times (repetitions: clustered cases): the rate Σ low / Σ overturned
    resampled by record, ours against scipy.stats.bootstrap (its own resampler, percentile method)."""
    rng = np.random.default_rng(11)
    over = rng.integers(1, 4, 40)
    low = rng.binomial(over, 0.7)
    ours = percentile_interval(mean_rate(low[None, :], over[None, :], cluster_resamples(40, 20000, seed=1)))
    theirs = bootstrap((low, over), lambda lo, ov, axis=-1: lo.sum(axis=axis) / ov.sum(axis=axis), paired=True,
                       vectorized=True, n_resamples=20000, method="percentile", random_state=2).confidence_interval
    assert ours == pytest.approx((theirs.low, theirs.high), abs=0.01)


def test_shared_records_give_no_narrower_interval_than_one_body() -> None:
    """Seven identical bodies on the same 25 records: the pooled counts are 7 × one body's, and Wilson's interval of
    them is √7 narrower; the records are the information, and the cluster bootstrap of the bodies' mean rate keeps
    the width of one body's."""
    rng = np.random.default_rng(5)
    one_low = (rng.random(25) < 0.8).astype(int)
    one_over = np.ones(25, dtype=int)
    low, over = np.tile(one_low, (7, 1)), np.tile(one_over, (7, 1))
    weights = cluster_resamples(25)
    body = percentile_interval(mean_rate(one_low[None, :], one_over[None, :], weights))
    average = percentile_interval(mean_rate(low, over, weights))
    assert average == pytest.approx(body)
    pooled = wilson_interval(int(low.sum()), int(over.sum()))
    assert pooled[1] - pooled[0] < 0.5 * (average[1] - average[0])


def test_mean_rate_leaves_out_groups_without_an_overturn() -> None:
    ones = np.ones((1, 3))
    low = np.array([[1, 1, 0], [0, 0, 0]])
    over = np.array([[1, 1, 1], [0, 0, 0]])
    assert mean_rate(low, over, ones)[0] == pytest.approx(2 / 3)
    assert math.isnan(mean_rate(low[1:], over[1:], ones)[0])


def test_fig13_rows_three_cases_resolve_nothing_and_25_against_5_is_different() -> None:
    """The demo's case: three runs of a body at an angle, the analysis 3 of 3 towards the low side, the experiment
    2 of 3 — a 33-point difference that one overturn makes: not resolved. 25 of 25 against 5 of 25 is different."""
    cases = [Case(4.0, 1, "rocking", 1, observed, f"r{k}") for k, observed in enumerate((1, 1, -1))]
    cases += [Case(5.0, 1, "rocking", 1, 1 if i < 5 else -1, f"r{i}") for i in range(25)]
    rows = {(r.angle_deg, r.body_id): r for r in fig13_rows(cases)}
    few, many = rows[(4.0, 1)], rows[(5.0, 1)]
    assert few.difference == pytest.approx(1 / 3)
    assert (few.cor_experiment_low, few.cor_experiment_high) == pytest.approx(wilson_interval(2, 3))
    expected = equivalence(3, 3, 2, 3, 0.05, cases=3)
    assert few.verdict == "not resolved" and few.runs_to_resolve == expected.cases_to_resolve > 3
    assert few.verdict_words() == f"not resolved with 3 runs (about {expected.cases_to_resolve} would)"
    assert (few.low_high, few.high_low, few.p_direction) == (1, 0, pytest.approx(mcnemar_exact(1, 0)))
    assert many.verdict == "different" and many.p_direction == pytest.approx(mcnemar_exact(20, 0))
    assert verdict_counts(fig13_rows(cases)) == {
        "rocking": {"equivalent": 0, "different": 1, "not resolved": 1, "undefined": 0}}


def test_fig13_average_row_is_the_mean_of_the_bodies_with_a_clustered_interval() -> None:
    """Two bodies on the same 30 records, overturning alike: the average row's rate is the mean of theirs and its
    interval the cluster bootstrap's (as wide as one body's Wilson interval, not the pooled counts')."""
    outcomes = [1] * 24 + [-1] * 6
    cases = [Case(4.0, body, "rocking", o, o, f"rec{k}") for body in (1, 2) for k, o in enumerate(outcomes)]
    rows = {r.body_id: r for r in fig13_rows(cases)}
    assert rows[0].cor_analysis == pytest.approx(0.8) and rows[0].records == 30 and rows[0].runs == 60
    body_width = rows[1].cor_analysis_high - rows[1].cor_analysis_low
    average_width = rows[0].cor_analysis_high - rows[0].cor_analysis_low
    pooled = wilson_interval(48, 60)
    assert average_width > pooled[1] - pooled[0] and abs(average_width - body_width) < 0.08
    assert rows[1].verdict == rows[0].verdict == "not resolved"  # identical rates, but 30 runs cannot show 5 points
    assert math.isnan(rows[0].p_direction) and rows[1].p_direction == 1.0


def test_fig13_a_record_whose_polarities_fall_either_way_keeps_its_rate() -> None:
    """One body, three records each in both polarities on a level plate: the analysis overturns it only on the
    first record, once each way (rate ½); the specimen on every record, once each way. Every resample gives a
    difference of 0 (or none), so each record counts once — at its rate ½, not rounded to 0 or 1."""
    cases = [Case(0.0, 1, "rocking", d if k == 0 else 0, d, f"r{k}") for k in range(3) for d in (1, -1)]
    row = next(r for r in fig13_rows(cases) if r.body_id == 1)
    assert (row.cor_analysis, row.cor_experiment, row.difference) == (0.5, 0.5, 0.0)
    assert (row.cor_analysis_low, row.cor_analysis_high) == pytest.approx(wilson_interval(0.5, 1))
    expected = equivalence(0.5, 1, 1.5, 3, 0.05, cases=6, overturn_fractions=(1 / 6, 3 / 6))
    assert (row.difference_low, row.difference_high) == pytest.approx((expected.low, expected.high))
    assert row.difference_low < 0 < row.difference_high and row.verdict == "not resolved"
