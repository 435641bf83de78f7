"""The emulator's specimens against the closed forms of rocking (``sim_table.characterise``, ``rig specimens
check``): Housner's restitution 1 − 1.5 sin²α within 5 %, Eq. 1's uplift accelerations within 2 %, the
linearised quarter period and Coulomb sliding within 2 %, and light bodies standing still on a tilted plate."""

from __future__ import annotations

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
from sim_table.scene import Specimen
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


@pytest.mark.parametrize("index", [3, 4])  # T5-4 and T5-5, 0.36 and 0.56 kg
def test_light_bodies_stand_still_on_a_tilted_plate(index: int) -> None:
    """With MuJoCo's default solver tolerance (1e-8) these bodies chattered on a 5° plate at rest (|θ| up to
    0.03 rad, creeping millimetres downhill): the plate's armature dominated Newton's cost."""
    pose = np.array([0.0, 0.0, 0.0, 0.0, TILT, 0.0])
    scene = SpecimenScene([Specimen(TABLE_V[index], friction=0.8)], plate_pose=pose)
    largest = 0.0
    for k in range(1, 1501):
        scene.advance(k * 1e-3, pose, np.zeros(6))
        largest = max(largest, abs(float(scene.specimen_angles()[0])))
    assert largest < 1e-4
    assert abs(scene.specimen_places()[0, 0]) < 1e-4


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
    bad = subprocess.run([str(rig), "specimens", "check", "--body", "0.1x0.5", "--tilt", "15"],
                         capture_output=True, text=True, timeout=300)  # α = 11.3°: it cannot stand at 15°
    assert bad.returncode == 2 and "would not stand" in bad.stderr, bad.stderr
