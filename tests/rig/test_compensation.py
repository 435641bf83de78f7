"""Drive compensation offline: the identification against the servo model's closed form, and the iteration's
convergence on the emulator's legs driven directly (sim_table.offline, no transport, no clock)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.body import TABLE_V
from analysis.table.model import TableModel
from rig.compensation.identify import frequency_response, identification_drive
from rig.compensation.iteration import compensate, motion_window
from rig.compensation.laws import MimoLaw
from rig.compensation.mimo import estimate
from rig.compensation.signals import base_accelerations, errors_pct, fall_line
from rig.drive import prepare_drive
from rig.records import load_record
from sim_table.dynamics import ServoActuators
from sim_table.offline import play_offline

TABLE = TableModel()
PAYLOAD = sum(body.mass for body in TABLE_V)
BETA = math.radians(5.0)


@pytest.fixture(scope="module")
def response():
    ident = identification_drive(TABLE, BETA, duration=40.0, seed=3)
    force = play_offline(TABLE, ident.poses, payload=PAYLOAD, seed=1)
    return frequency_response(ident.accelerations[:, :3], base_accelerations(force, BETA), TABLE.controller_rate)


def test_error_measures_closed_form():
    t = np.linspace(0, 1, 1001)
    target = np.sin(2 * math.pi * 3 * t)
    assert errors_pct(1.1 * target, target) == pytest.approx((10.0, 10.0))
    assert errors_pct(target + 0.05, target)[0] == pytest.approx(100 * 0.05 / math.sqrt(0.5), rel=1e-3)
    with pytest.raises(ValueError, match="zero"):
        errors_pct(target, 0 * target)


def test_fall_line_of_a_tilted_plate_at_rest_is_zero():
    g = 9.81
    force = np.array([[-g * math.sin(BETA), 0.0, g * math.cos(BETA)]])
    acc = base_accelerations(force, BETA)
    assert acc == pytest.approx(np.zeros((1, 3)), abs=1e-12)
    assert fall_line(np.array([[1.0, 0.0, 0.0]]), BETA)[0] == pytest.approx(math.cos(BETA))


def test_identification_drive_stays_inside_table_iv():
    drive = identification_drive(TABLE, BETA, duration=20.0, level=0.5)
    assert TABLE.check_trajectory(drive.t, drive.poses) is None
    for column, axis in enumerate(("surge", "lateral", "heave")):
        limits = TABLE.limits.axis(axis)
        assert np.abs(drive.accelerations[:, column]).max() <= 0.5 * limits.acceleration * 1.01
    assert np.all(drive.poses[:, 4] == BETA)


def test_identified_response_matches_the_servo_closed_loop(response):
    """For small motion the plate follows its response matrix J⁻¹ U diag(H_j) Uᵀ J (the legs' sampled loops per mode,
    built with scipy.signal, at the tilt): with uncorrelated surge, lateral and heave excitation the H1 estimate of
    each axis is that matrix's diagonal element, the accelerometer's surge also reading the pitch the surge couples
    into as gravity (−g δθ, rotated back by the nominal tilt): H = H_xx + g H_θx / ω². It must find it where the
    coherence is high. The ordinary coherence of surge is no longer ~1 everywhere: at the tilt the lateral and heave
    excitation leak into the surge reading through the plate's coupled modes (the multiple coherence would be)."""
    dt = 1.0 / TABLE.controller_rate
    legs = ServoActuators(TABLE, dt, payload=PAYLOAD, pose=np.array([0.0, 0.0, 0.0, 0.0, BETA, 0.0]))
    freqs = np.array([1.0, 3.0, 6.0, 10.0, 13.0, 20.0])  # not on the surge resonance (4 Hz, coherence 0.7)
    matrix = legs.frequency_response(freqs)
    expected = {0: matrix[:, 0, 0] + 9.80665 * matrix[:, 4, 0] / (2 * math.pi * freqs) ** 2, 2: matrix[:, 2, 2]}
    h, coherence = response.at(freqs)
    assert np.all(coherence[:, 0] > 0.9) and np.all(coherence[:, 2] > 0.98)
    for column in (0, 2):
        moving = np.abs(expected[column]) > 0.1  # not surge at 20 Hz (0.05), where the leaks dominate the reading
        assert np.abs(h[moving, column]) == pytest.approx(np.abs(expected[column][moving]), rel=0.05)
        assert np.angle(h[moving, column] / expected[column][moving]) == pytest.approx(np.zeros(moving.sum()),
                                                                                        abs=math.radians(4))
    assert np.abs(h[:, 0]).max() > 1.8  # the surge modes' resonance shows at 3 Hz


@pytest.mark.parametrize("angle_deg", [0.0, 5.0])
def test_iteration_converges_on_the_servo_table(angle_deg):
    """A FEMA record uncompensated on the coupled servo table (the first play, at −12 dB): ≥ 20 % fall-line RMS
    error; the MIMO law (the default) halves it by the −6 dB play and brings it to ≤ 2.5 % within three full-level
    plays (issue 23's target is 5 %; 1.4 and 1.3 % measured at 0° and 5° with ε = 0.001 and the flat gain to 50 Hz,
    4.6 % with ε = 0.01), every
    played command within what the table enforces
    (``TableModel.check_command``) and the plate's achieved acceleration within Table IV."""
    beta = math.radians(angle_deg)
    ident = identification_drive(TABLE, beta, duration=40.0, seed=4)
    measured = base_accelerations(play_offline(TABLE, ident.poses, payload=PAYLOAD, seed=2), beta)
    matrix = estimate(ident.accelerations[:, :3], measured, TABLE.controller_rate)
    drive = prepare_drive(load_record("fema:NORTHR/MUL009"), angle=beta, table=TABLE, ramps=False, headroom=0.1)
    played = []

    def play(d, k):
        played.append(d)
        return play_offline(TABLE, d.poses, payload=PAYLOAD, seed=10 + k)

    result = compensate(drive, MimoLaw(matrix), play, iterations=3)
    errors = [it.rms_error_pct for it in result.iterations]
    assert [it.level_db for it in result.iterations] == [-12.0, -6.0, 0.0, 0.0, 0.0]
    assert errors[0] >= 20.0
    assert errors[1] < errors[0] / 2
    assert min(errors[2:]) <= 2.5 and errors[4] < errors[2]
    assert result.iterations[result.best].rms_error_pct == min(errors[2:])
    for d in played:  # the commands within what the table enforces, the plate's response within Table IV
        assert TABLE.check_command(d.t, d.poses, d.velocities, d.accelerations) is None
    assert max(it.measures.peak_to_limit for it in result.iterations) <= 1.0
    motion, window = motion_window(drive)
    outside = np.ones(len(drive.t), bool)
    outside[motion] = False
    assert np.array_equal(result.drive.poses[outside], drive.poses[outside])  # corrections only in the record
    assert window.max() == 1.0


def test_the_lag_table_needs_little_compensation(response):
    """On the default first-order 5 ms lag the drive is already reproduced within a few percent."""
    drive = prepare_drive(load_record("fema:NORTHR/MUL009"), angle=BETA, table=TABLE, ramps=False)
    measured = base_accelerations(play_offline(TABLE, drive.poses, dynamics="lag", payload=PAYLOAD), BETA)
    motion, _ = motion_window(drive)
    rms, _ = errors_pct(fall_line(measured, BETA)[motion], fall_line(drive.accelerations[:, :3], BETA)[motion])
    assert rms < 15.0


def test_noise_floor_is_the_accelerometers_noise_in_the_error_band():
    """The noise floor a play reports is its accelerometer's white noise (σ over the 500 Hz of 1 kHz samples) in the
    error band — the fourth-order Butterworth low-pass at 50 Hz run forward and backward, |H|⁴, whose noise
    bandwidth is 50 Hz · (π/16)/sin(π/16) — over the target's fall-line RMS: the closed form within 10 % (the
    estimate's own scatter on the 1 s of stillness before the motion is about 7 %)."""
    from rig.compensation.iteration import error_window, target_acceleration
    from rig.compensation.measures import measure
    from rig.compensation.signals import in_band

    drive = prepare_drive(load_record("fema:NORTHR/MUL009"), angle=BETA, table=TABLE, ramps=False, headroom=0.1)
    sigma = 0.05
    force = play_offline(TABLE, drive.poses, payload=PAYLOAD, seed=5, accel_noise=sigma, leg_noise=0.0)
    window = error_window(drive)
    target = target_acceleration(drive)
    measures = measure(drive, target, base_accelerations(force, BETA), window, 50.0)
    target_rms = float(np.sqrt(np.mean(in_band(fall_line(target, BETA), drive.rate)[window] ** 2)))
    bandwidth = 50.0 * (math.pi / 16) / math.sin(math.pi / 16)
    expected = 100.0 * sigma * math.sqrt(bandwidth / 500.0) / target_rms
    assert measures.noise_floor_pct == pytest.approx(expected, rel=0.10)


def test_near_the_noise_floor_the_gain_falls_and_the_error_ends_lower_than_at_full_gain(monkeypatch):
    """With a noisy accelerometer (σ = 0.1 m/s²: a floor of several percent, far above what the MIMO law leaves on
    this record) a correction at full gain plays the noise back (a gain g on white noise leaves g/(2 − g) of the
    floor's square in the table's error: √2 × the floor at g = 1 without the law's coherence weighting and the
    best-of-plays choice, which hold it lower). The Wiener factor 1 − N²/M² ends lower, never below the floor,
    which no play can beat."""
    import rig.compensation.iteration as iteration

    beta = BETA
    ident = identification_drive(TABLE, beta, duration=40.0, seed=4)
    measured = base_accelerations(play_offline(TABLE, ident.poses, payload=PAYLOAD, seed=2), beta)
    matrix = estimate(ident.accelerations[:, :3], measured, TABLE.controller_rate)
    drive = prepare_drive(load_record("fema:NORTHR/MUL009"), angle=beta, table=TABLE, ramps=False, headroom=0.1)

    def play(d, k):
        return play_offline(TABLE, d.poses, payload=PAYLOAD, seed=10 + k, accel_noise=0.1)

    wiener = compensate(drive, MimoLaw(matrix), play, iterations=5)
    with monkeypatch.context() as patch:
        patch.setattr(iteration, "noise_gain", lambda error_pct, floor_pct: 1.0)
        full = compensate(drive, MimoLaw(matrix), play, iterations=5)
    best_w, best_f = wiener.iterations[wiener.best], full.iterations[full.best]
    floor = iteration.pooled_floor(wiener.iterations)  # the sensor's noise, from every play's stillness
    assert floor is not None and floor > 3.0
    assert floor * 0.95 <= best_w.rms_error_pct < best_f.rms_error_pct
    assert best_f.rms_error_pct > 1.1 * floor
    assert iteration.noise_gain(2.0, 1.0) == 0.75 and iteration.noise_gain(2.0, None) == 1.0
    assert iteration.noise_gain(1.0, 2.0) == 0.0
    assert any("near the noise floor" in it.note for it in wiener.iterations)
