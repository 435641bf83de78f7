"""Fast engine against the reference on real records (issue: ≥ 99.5 % same direction, COR within
0.5 percentage points per angle, every difference explained by chaos); for the general model also
the stressed set (μ 0.1–0.6, vertical input in half, both signs, 0–10°), slide displacement included."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis import TABLE_I
from analysis.verification import (
    Agreement,
    StressedAgreement,
    compare_stressed,
    compare_with_reference,
    stressed_scenes,
)
from rig.records import load_records

ANGLES = [math.radians(a) for a in (0.0, 3.0, 5.0, 7.0)]


def check(ag: Agreement) -> None:
    assert ag.fraction_same >= 0.995, f"{ag.scenes - ag.same_direction} of {ag.scenes} scenes differ"
    assert ag.max_cor_difference_pp <= 0.5
    assert not ag.unexplained, f"differences that a 1e-6 perturbation does not explain: {ag.unexplained}"


def test_fast_matches_reference_on_a_sample_of_fema_scenes() -> None:
    records = load_records("fema")[::10]
    ag = compare_with_reference(list(TABLE_I[::4]), records, ANGLES[1:3], processes=2)
    assert ag.scenes == 3 * 10 * 2 * 2
    check(ag)
    assert ag.t_overturn_max_error < 1e-4


@pytest.mark.slow
@pytest.mark.parametrize("model", ["rocking", "general"])
def test_fast_matches_reference_on_all_fema_components(model: str) -> None:
    """All 100 FEMA P695 components × both signs × the 12 Table I bodies at 0°, 3°, 5° and 7°."""
    if model == "general":
        pytest.importorskip("analysis.fast_general")
    ag = compare_with_reference(list(TABLE_I), load_records("fema"), ANGLES, model=model, processes=2)
    assert ag.scenes == 12 * 100 * 2 * 4
    check(ag)
    # at 0° the two signs of a record mirror each other: COR is exactly 50 % in both solvers
    assert ag.cor_reference[0]["cor"] == pytest.approx(0.5) and ag.cor_fast[0]["cor"] == pytest.approx(0.5)
    assert np.count_nonzero(ag.reference_direction) > 1000  # the set really exercises overturning


def check_stressed(ag: StressedAgreement) -> None:
    assert not ag.unexplained, f"differences that a 1e-6 perturbation does not explain: {ag.unexplained}"
    assert ag.same_outcome >= 0.99 * ag.scenes
    # the slide: exact in SLIDE and FLIGHT, order 4 in ROCKSLIDE (fast); DOP853 at rtol 1e-11 (reference)
    assert ag.slide_residual_max_error_m <= 1e-6 and ag.slide_peak_max_error_m <= 1e-6
    assert ag.slide_time_max_error_s <= 1e-6
    assert ag.t_overturn_max_error_s <= 1e-3


def test_slide_agrees_on_a_few_stressed_scenes() -> None:
    ag = compare_stressed(stressed_scenes(list(TABLE_I), load_records("fema"), 6, seed=7), processes=2)
    check_stressed(ag)
    assert ag.sliding >= 3


@pytest.mark.slow
def test_fast_matches_reference_on_the_stressed_set() -> None:
    """120 scenes: Table I bodies × FEMA components, μ uniform in [0.1, 0.6], either sign, β in
    [0°, 10°], a vertical input (the partner component, peak 0.3–1.5 g) in half of them — the first
    120 of benchmarks/engine.py's 600 (same seed; a scene's draws depend only on those before it)."""
    ag = compare_stressed(stressed_scenes(list(TABLE_I), load_records("fema"), 120, seed=26), processes=2)
    check_stressed(ag)
    assert ag.sliding >= 60 and ag.overturned >= 10 and ag.with_vertical >= 40  # the set does stress it
