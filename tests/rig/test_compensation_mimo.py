"""The response matrix and its inverse against closed forms: a known linear 3×3 system built with scipy.signal
(H1 recovers it, the multiple coherence is its signal-to-noise share, the condition number is that of its freqz
matrix), the Tikhonov inverse against its normal equations, and one exact step on a noiseless linear plant."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from analysis.body import G
from analysis.table.model import TableModel
from rig.compensation.identify import frequency_response, identification_drive
from rig.compensation.iteration import compensate
from rig.compensation.laws import MimoLaw
from rig.compensation.mimo import estimate, tikhonov_inverse
from rig.drive import prepare_drive
from rig.records import load_record

RATE = 1000.0
TABLE = TableModel()


def _plant() -> list[list[tuple[np.ndarray, np.ndarray]]]:
    """(b, a) from input k to output j: unit-DC resonant direct terms (8, 11, 14 Hz, 20 % damping), band-pass
    cross terms (zero DC) of gain ~0.1-0.3 — a coupled table-like system, discretised with the bilinear
    transform."""
    plant = []
    for j in range(3):
        row = []
        for k in range(3):
            if j == k:
                w = 2 * math.pi * (8.0 + 3.0 * j)
                b, a = signal.bilinear([w**2], [1.0, 2 * 0.2 * w, w**2], fs=RATE)
            else:
                w = 2 * math.pi * (5.0 + 2.0 * j + k)
                b, a = signal.bilinear([0.1 * (1 + j) * 2 * 0.3 * w, 0.0], [1.0, 2 * 0.3 * w, w**2], fs=RATE)
            row.append((b, a))
        plant.append(row)
    return plant


PLANT = _plant()


def _through(x: np.ndarray) -> np.ndarray:
    """The plant's outputs (n, 3) for inputs (n, 3)."""
    return np.column_stack([sum(signal.lfilter(*PLANT[j][k], x[:, k]) for k in range(3)) for j in range(3)])


def _freqz(freqs: np.ndarray) -> np.ndarray:
    """The plant's matrix (m, 3, 3) at ``freqs`` [Hz]."""
    out = np.zeros((len(freqs), 3, 3), complex)
    for j in range(3):
        for k in range(3):
            out[:, j, k] = signal.freqz(*PLANT[j][k], worN=freqs, fs=RATE)[1]
    return out


def test_h1_recovers_a_known_mimo_system_with_its_coherence_and_condition():
    rng = np.random.default_rng(5)
    x = rng.normal(size=(400_000, 3))
    clean = _through(x)
    noise = 0.05
    y = clean + noise * rng.normal(size=clean.shape)
    response = estimate(x, y, RATE, band=(0.5, 50.0), nperseg=4096)
    lines = (response.f >= 1.0) & (response.f <= 20.0)
    exact = _freqz(response.f[lines])
    assert np.abs(response.h[lines] - exact).max() < 0.025 * np.abs(exact).max()
    # multiple coherence: each output's share of power explained by the inputs (unit variance each) over the noise
    power = (np.abs(exact) ** 2).sum(axis=2)
    expected = power / (power + noise**2)
    assert response.coherence[lines] == pytest.approx(expected, abs=0.02)
    assert response.condition[lines] == pytest.approx(np.linalg.cond(exact), rel=0.05)
    assert np.all(response.h[response.f > 50.0] == 0)


def test_correlated_inputs_are_refused():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(20_000, 1)) * np.ones((1, 3))
    with pytest.raises(ValueError, match="not independent"):
        estimate(x, _through(x), RATE, band=(1.0, 40.0), nperseg=1024)


def test_tikhonov_inverse_against_the_normal_equations():
    rng = np.random.default_rng(2)
    h = rng.normal(size=(7, 3, 3)) + 1j * rng.normal(size=(7, 3, 3))
    h[0, :, 2] = h[0, :, 1] + 1e-4 * rng.normal(size=3)  # one nearly singular line
    for eps in (0.0, 1e-3, 0.1):
        got = tikhonov_inverse(h, eps)
        for m in range(len(h)):
            smax = np.linalg.svd(h[m], compute_uv=False)[0]
            hh = h[m].conj().T
            want = np.linalg.solve(hh @ h[m] + eps * smax**2 * np.eye(3), hh) if eps else np.linalg.inv(h[m])
            assert got[m] == pytest.approx(want, rel=1e-6, abs=1e-9 * np.abs(want).max())
            # the gain of the inverse is bounded by max σ/(σ² + ε σmax²) = 1/(2 √ε σmax): nothing is amplified more
            if eps:
                assert np.linalg.svd(got[m], compute_uv=False)[0] <= 1 / (2 * math.sqrt(eps) * smax) * (1 + 1e-9)
    assert np.linalg.svd(tikhonov_inverse(h[:1], 0.0)[0], compute_uv=False)[0] > 1e3  # unregularised: amplified


def test_one_exact_step_on_a_noiseless_linear_plant_converges():
    """The plant above as the table (no noise): identified from the random drive, one correction with gain 1 and a
    negligible ε takes the error from tens of percent to well under 1 %."""
    def play(drive, _index):  # plate-frame specific force of a level plate: a − g
        force = _through(drive.accelerations[:, :3])
        force[:, 2] += G
        return force

    ident = identification_drive(TABLE, 0.0, duration=60.0, seed=8)
    law = MimoLaw(estimate(ident.accelerations[:, :3], play(ident, 0)[:, :3] - [0, 0, G], RATE, band=(0.5, 50.0)),
                  gain=1.0, gain_high=1.0, regularisation=1e-9)
    drive = prepare_drive(load_record("fema:NORTHR/MUL009"), angle=0.0, table=TABLE, ramps=False, headroom=0.3)
    result = compensate(drive, law, play, iterations=1, levels_db=(-6.0, 0.0))
    before, after = (it.rms_error_pct for it in result.iterations)
    assert before > 20.0
    assert after < 1.0
    assert result.iterations[1].measures.fall_line["trac"] > 0.9999


def test_the_response_between_the_band_edge_and_the_first_identified_line_is_that_line():
    """A table that doubles every motion, identified over 0.5–50 Hz with 4096-sample segments (lines every
    0.244 Hz: 0.488 Hz outside the band, 0.732 Hz the first inside): at 0.5 and 0.6 Hz the matrix and the per-axis
    response are 2, as at 0.732 Hz — not a ramp from the zero kept outside the band (0.1 at 0.5 Hz) — with the
    coherence of that line; and so is the prediction the safety check makes there."""
    x = np.random.default_rng(5).normal(size=(60_000, 3))
    matrix = estimate(x, 2.0 * x, RATE, band=(0.5, 50.0))
    diagonal = frequency_response(x, 2.0 * x, RATE, band=(0.5, 50.0))
    assert matrix.f[2] < 0.5 < matrix.f[3]
    freqs = np.array([0.5, 0.6, matrix.f[3]])
    h, coherence = matrix.at(freqs)
    assert h == pytest.approx(np.broadcast_to(2.0 * np.eye(3), (3, 3, 3)), abs=1e-9)
    assert coherence == pytest.approx(np.ones((3, 3)))
    h, coherence = diagonal.at(freqs)
    assert h == pytest.approx(np.full((3, 3), 2.0), abs=1e-9) and coherence == pytest.approx(np.ones((3, 3)))
    spectrum = np.ones((3, 3), complex)
    assert matrix.apply(freqs, spectrum) == pytest.approx(2.0 * spectrum)
