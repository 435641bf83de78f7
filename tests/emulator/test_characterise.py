"""The emulator's specimens against the closed forms of rocking (``sim_table.characterise``, ``rig specimens
check``): Housner's restitution 1 − 1.5 sin²α within 5 %, Eq. 1's uplift accelerations within 2 %, the
linearised quarter period and Coulomb sliding within 2 %, and light bodies standing still on a tilted plate."""

from __future__ import annotations

import itertools
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from analysis import TABLE_V
from analysis.restitution import fit_restitution, impact_ratios
from sim_table.characterise import characterise, free_rocking
from sim_table.scene import Specimen, parse_body
from sim_table.specimens import SpecimenScene

TILT = math.radians(5.0)


@pytest.mark.parametrize("index", [3, 6])  # T5-4, the lightest (0.36 kg), and T5-7, the heaviest (65 kg)
def test_a_table_v_body_matches_the_closed_forms(index: int) -> None:
    result = characterise(Specimen(TABLE_V[index], friction=0.8), TILT)
    errors = result.errors()
    assert abs(errors["restitution"]) < 0.05, result
    assert abs(errors["uplift_low"]) < 0.02 and abs(errors["uplift_high"]) < 0.02, result
    assert abs(errors["quarter_period"]) < 0.02, result
    assert abs(errors["sliding"]) < 0.02, result
    assert result.uplift_g["low"] < result.uplift_g["high"]  # the tilt favours the low side (Eq. 1)


def test_an_off_centre_table_v_body_shows_each_sides_slenderness_and_impact() -> None:
    """T5-1 as printed (centre of mass 47.5 mm from its +x corner, 51.5 mm from its −x corner, 243 mm up): the uplift
    on each side at 5° meets Eq. 1 with that side's α (α+ = 11.06°, α− = 11.97°; the centred block's 11.36° would be
    5 % off on the low side), the slenderness it shows on each side is the body's within 0.15°, and the
    free-rocking restitution and quarter period on each side meet Housner's per direction and the linearised closed
    form with that side's p."""
    body = TABLE_V[0]
    result = characterise(Specimen(body, friction=0.8), TILT)
    errors = result.errors()
    assert result.slenderness_deg == pytest.approx({"plus": 11.0603, "minus": 11.9659}, abs=1e-4)
    assert abs(errors["uplift_low"]) < 0.02 and abs(errors["uplift_high"]) < 0.02, result
    assert abs(errors["slenderness_plus_deg"]) < 0.15 and abs(errors["slenderness_minus_deg"]) < 0.15, result
    measured = result.slenderness_measured_deg
    assert measured["minus"] - measured["plus"] == pytest.approx(11.9659 - 11.0603, abs=0.3)
    centred_low = math.tan(body.alpha - TILT)
    assert abs(result.uplift_g["low"] / centred_low - 1.0) > 0.03  # not the centred block's threshold
    assert (result.restitution_housner, result.restitution_housner_minus) == body.housner_restitutions()
    assert abs(errors["restitution"]) < 0.05 and abs(errors["restitution_minus"]) < 0.05, result
    assert abs(errors["quarter_period"]) < 0.02 and abs(errors["quarter_period_minus"]) < 0.02, result
    assert (result.b_cg, result.h_cg) == (0.0515, 0.243)


@pytest.mark.parametrize("index", [0, 2])  # T5-1 and T5-3: Housner's e 0.94 and 0.87
def test_the_restitution_read_at_the_impacts_matches_the_one_read_from_the_amplitudes(index: int) -> None:
    """`analysis.restitution` (what ``rig analyze --restitution fit`` uses: rates across each impact from the
    tilt sensor's 200 Hz samples) on the specimen's free rocking agrees with the characterisation's energy
    method (two amplitudes) within 2 %: the soft contact's few-millisecond impact does not bias it."""
    specimen = Specimen(TABLE_V[index])
    from_amplitudes, _ = free_rocking(specimen)
    scene = SpecimenScene([specimen])
    scene.place(leans=[0.5 * specimen.body.alpha])
    times = np.arange(1, 4001) * 1e-3
    angles = np.empty(times.size)
    still = np.zeros(6)
    for k, t in enumerate(times):
        scene.advance(float(t), still, still)
        angles[k] = scene.specimen_angles()[0]
    fit = fit_restitution(impact_ratios(times[4::5], angles[4::5]))
    assert fit.impacts >= 10
    assert fit.value == pytest.approx(from_amplitudes, rel=0.02)


@pytest.mark.parametrize(("index", "restitution"), [(0, 0.85), (3, 0.7), (2, 0.95)])
def test_a_body_given_a_measured_restitution_reproduces_it_and_nothing_else_changes(index: int,
                                                                                   restitution: float) -> None:
    """The impact model (sim_table/specimens.py): the restitution read from the amplitudes is the one set, within
    the issue's 5 % (T5-3's 0.95 is above its contact's own 0.87: the factor > 1); between impacts the body rocks
    as before, so the quarter period and the uplift accelerations keep their closed forms."""
    result = characterise(Specimen(TABLE_V[index], friction=0.8, restitution=restitution), TILT)
    errors = result.errors()
    assert result.restitution_target == restitution
    assert result.restitution == pytest.approx(restitution, rel=0.05)
    assert abs(errors["quarter_period"]) < 0.02 and abs(errors["uplift_low"]) < 0.02, result
    assert abs(errors["uplift_high"]) < 0.02, result


def test_a_set_restitution_holds_at_every_impact_of_the_free_rocking() -> None:
    """T5-1 set to 0.85 (its contact gives 0.94), released at α/2: the rates across each impact read from the
    200 Hz tilt samples (`analysis.restitution`, what `rig analyze --restitution fit` uses) give 0.85 within 5 %
    over the whole decay, and each amplitude is the closed-form one of the previous times e (energy conserved
    between impacts), not only the first."""
    specimen = Specimen(TABLE_V[0], restitution=0.85)
    body = specimen.body  # its centre of mass is off the middle: each corner's α and p (α+ on the release side)
    scene = SpecimenScene([specimen])
    scene.place(leans=[0.5 * body.alpha_plus])
    times = np.arange(1, 4001) * 1e-3
    still = np.zeros((times.size, 6))
    parts = []
    for k in range(0, times.size, 80):  # as the emulator steps it: batches in C
        scene.advance_many(times[k:k + 80], still[k:k + 80], still[k:k + 80])
        parts.append(scene.sample_angles[:, 0])
    angles = np.concatenate(parts)
    fit = fit_restitution(impact_ratios(times[4::5], angles[4::5]))
    assert fit.impacts >= 5
    assert fit.value == pytest.approx(0.85, rel=0.05)
    crossings = np.flatnonzero(np.sign(angles[1:]) != np.sign(angles[:-1]))
    peaks = [float(np.abs(angles[a:b]).max()) for a, b in itertools.pairwise(crossings)][:4]
    peaks.insert(0, 0.5 * body.alpha_plus)

    def rate(amplitude: float, n: int) -> float:  # |θ'| at θ = 0 after rising to ``amplitude`` on the n-th lean
        alpha, p = (body.alpha_plus, body.p_plus) if n % 2 == 0 else (body.alpha_minus, body.p_minus)
        return p * math.sqrt(2.0 * (math.cos(alpha - amplitude) - math.cos(alpha)))

    ratios = [rate(after, n + 1) / rate(before, n) for n, (before, after) in enumerate(itertools.pairwise(peaks))]
    assert len(ratios) == 4 and all(r == pytest.approx(0.85, rel=0.05) for r in ratios), ratios


def test_the_impact_model_steps_a_batch_as_it_steps_each_sample() -> None:
    """advance_many cuts its rollout at an impact and steps on from the scaled state: the same angles as advance,
    sample by sample, within 1e-5 rad (the bar of the unscaled batches, test_specimens; without the impact model
    the two differ by 1.6e-6 here, and a missed impact would leave its velocity 0.8/0.87 of what it should be)."""
    specimen = Specimen(TABLE_V[2], restitution=0.8)
    times = np.arange(1, 1501) * 1e-3
    still = np.zeros((times.size, 6))
    one, batched = SpecimenScene([specimen]), SpecimenScene([specimen])
    for scene in (one, batched):
        scene.place(leans=[0.5 * specimen.body.alpha])
    singles = []
    for k, t in enumerate(times):
        one.advance(float(t), still[k], still[k])
        singles.append(one.sample_angles[0, 0])
    batches = []
    for k in range(0, times.size, 80):
        batched.advance_many(times[k:k + 80], still[k:k + 80], still[k:k + 80])
        batches.append(batched.sample_angles[:, 0])
    assert np.abs(np.concatenate(batches) - np.array(singles)).max() < 1e-5


def at_rest_on_the_tilt(specimen: Specimen) -> tuple[SpecimenScene, float]:
    """``specimen`` placed on a plate held at the 5° tilt for 1.5 s: the scene, and the largest |θ| [rad] seen."""
    pose = np.array([0.0, 0.0, 0.0, 0.0, TILT, 0.0])
    scene = SpecimenScene([specimen], plate_pose=pose)
    largest = 0.0
    for k in range(1, 1501):
        scene.advance(k * 1e-3, pose, np.zeros(6))
        largest = max(largest, abs(float(scene.specimen_angles()[0])))
    return scene, largest


def test_a_body_set_above_its_contacts_restitution_still_stands_still_on_a_tilted_plate() -> None:
    """The factor > 1 of T5-3 set to 0.95 scales impacts only: the contact's jitter of a body at rest (< 1e-5 rad,
    below IMPACT_LEAN) is never taken for one and amplified."""
    _, largest = at_rest_on_the_tilt(Specimen(TABLE_V[2], friction=0.8, restitution=0.95))
    assert largest < 1e-4


def test_a_restitution_outside_the_model_is_refused() -> None:
    with pytest.raises(ValueError, match=r"restitution must be in \(0, 1\], got 1.2"):
        Specimen(TABLE_V[0], restitution=1.2)
    with pytest.raises(ValueError, match="too stocky for the impact model"):
        parse_body("1.0x0.6;restitution=0.5")
    with pytest.raises(ValueError, match=r"unknown option\(s\) e \(depth, mass, mu, restitution, cg\)"):
        parse_body("0.1x0.5;e=0.5")


@pytest.mark.parametrize("index", [3, 4])  # T5-4 and T5-5, 0.36 and 0.56 kg
def test_light_bodies_stand_still_on_a_tilted_plate(index: int) -> None:
    """With MuJoCo's default solver tolerance (1e-8) these bodies chattered on a 5° plate at rest (|θ| up to
    0.03 rad, creeping millimetres downhill): the plate's armature dominated Newton's cost."""
    body = TABLE_V[index]
    scene, largest = at_rest_on_the_tilt(Specimen(body, friction=0.8))
    assert largest < 1e-4
    # the point under its centre of mass, b_cg − b/2 from the base's centre (T5-5: 0.5 mm), has not crept
    assert abs(scene.specimen_places()[0, 0] - (body.cg[0] - 0.5 * body.b)) < 1e-4


@pytest.mark.integration
def test_rig_specimens_check_prints_json_for_a_body(tmp_path: Path) -> None:
    rig = Path(sys.executable).with_name("rig")
    done = subprocess.run([str(rig), "specimens", "check", "--body", "0.1x0.5", "--tilt", "4", "--json"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    (body,) = json.loads(done.stdout)["bodies"]
    for key in ("restitution", "restitution_housner", "uplift_g", "uplift_eq1_g", "quarter_period_s",
                "quarter_period_closed_form_s", "sliding_g", "sliding_mu"):
        assert key in body
    assert body["uplift_eq1_g"]["low"] == pytest.approx(math.tan(math.atan(0.2) - math.radians(4)))


@pytest.mark.integration
def test_rig_specimens_check_measures_a_sequence_body_against_its_set_restitution(tmp_path: Path) -> None:
    rig = Path(sys.executable).with_name("rig")
    sequence = tmp_path / "seq.toml"
    sequence.write_text('name = "s"\nangles_deg = [0]\nrecords = ["fema:NORTHR/MUL009"]\n\n[[bodies]]\n'
                        'b = 0.1\nh = 0.5\ndepth = 0.2\nmass = 6\nx = 0.0\ny = 0.0\nrestitution = 0.85\n')
    done = subprocess.run([str(rig), "specimens", "check", "--sequence", str(sequence), "--json"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    (body,) = json.loads(done.stdout)["bodies"]
    assert body["restitution_target"] == 0.85 and body["restitution_housner"] == pytest.approx(1 - 1.5 / 26)
    assert body["restitution"] == pytest.approx(0.85, rel=0.05)
    assert body["errors"]["restitution"] == pytest.approx(body["restitution"] / 0.85 - 1)
    bad = subprocess.run([str(rig), "specimens", "check", "--body", "0.1x0.5", "--tilt", "15"],
                         capture_output=True, text=True, timeout=300)  # α = 11.3°: it cannot stand at 15°
    assert bad.returncode == 2 and "would not stand" in bad.stderr, bad.stderr
