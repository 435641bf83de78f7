"""Drive preparation against closed forms, Table IV and the hexapod's legs (issue 3)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import signal
from typer.testing import CliRunner

from analysis.table.model import TABLE_IV, AxisLimits, HexapodGeometry, TableLimits, TableModel
from rig.cli import app
from rig.drive import Drive, DriveError, DriveRefusedError, prepare_drive, processing, tilt
from rig.drive.prepare import FC_MIN
from rig.records import G, GroundMotion, load_records

AXIS_COLUMN = {"surge": 0, "lateral": 1, "heave": 2}


# --------------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------------


def burst(amplitude: float, freq: float, cycles: int, dt: float, quiet: float = 3.0):
    """A displacement burst d = D sin(2πft)·sin²(πt/T) on [0, T] with quiet seconds before and after.

    Returns time, displacement [m], velocity [m/s] and acceleration [m/s²] in closed form.
    """
    T = cycles / freq
    t = np.arange(round((T + 2 * quiet) / dt) + 1) * dt
    s = np.clip(t - quiet, 0.0, T)
    inside = (t >= quiet) & (t <= quiet + T)
    w = 2 * np.pi * freq
    k = np.pi / T
    sin, cos = np.sin(w * s), np.cos(w * s)
    env, denv, ddenv = np.sin(k * s) ** 2, k * np.sin(2 * k * s), 2 * k**2 * np.cos(2 * k * s)
    disp = amplitude * sin * env
    vel = amplitude * (w * cos * env + sin * denv)
    acc = amplitude * (-(w**2) * sin * env + 2 * w * cos * denv + sin * ddenv)
    return t, disp * inside, vel * inside, acc * inside


def at_record_times(drive: Drive, motion: GroundMotion, values: np.ndarray) -> np.ndarray:
    """``values`` of the drive (sampled at drive.rate) at the record's own sample instants."""
    index = np.rint((drive.record_start + motion.time) * drive.rate).astype(int)
    return values[index]


def assert_inside_limits(drive: Drive, limits: TableLimits = TABLE_IV) -> None:
    """Peaks of the commanded channels, and of the finite differences of the commanded positions."""
    for axis, col in AXIS_COLUMN.items():
        bounds = limits.axis(axis)
        for quantity, values in (("displacement", drive.poses), ("velocity", drive.velocities),
                                 ("acceleration", drive.accelerations)):
            peak = np.max(np.abs(values[:, col]))
            assert peak <= getattr(bounds, quantity) * (1 + 1e-9), (drive.record, axis, quantity, peak)
        fd_vel = np.gradient(drive.poses[:, col], drive.t)
        assert np.max(np.abs(fd_vel)) <= bounds.velocity * 1.002, (drive.record, axis, "finite-difference velocity")


def assert_starts_and_ends_home(drive: Drive) -> None:
    for values in (drive.poses, drive.velocities, drive.accelerations):
        assert np.max(np.abs(values[0])) < 1e-9
        assert np.max(np.abs(values[-1])) < 1e-9


# --------------------------------------------------------------------------------------------------
# processing chain: closed forms
# --------------------------------------------------------------------------------------------------


def test_integration_of_a_sine_matches_the_closed_form() -> None:
    dt, w = 0.001, 2 * np.pi * 1.5
    t = np.arange(4001) * dt
    vel, disp = processing.integrate_from_rest(np.sin(w * t), dt)
    # the trapezoid's error is (ω dt)²/12 of the peak: 7e-6 here
    np.testing.assert_allclose(vel, (1 - np.cos(w * t)) / w, atol=1e-5 * (2 / w))
    np.testing.assert_allclose(disp, t / w - np.sin(w * t) / w**2, atol=1e-5 * (4.0 / w))


def test_end_correction_matches_the_six_end_conditions() -> None:
    dt, n = 0.01, 501
    p, dp, ddp = processing.end_correction(n, dt, (0.3, -0.2, 1.5), (-0.1, 0.4, -2.0))
    assert (p[0], dp[0], ddp[0]) == pytest.approx((0.3, -0.2, 1.5), abs=1e-12)
    assert (p[-1], dp[-1], ddp[-1]) == pytest.approx((-0.1, 0.4, -2.0), abs=1e-12)
    np.testing.assert_allclose(np.gradient(p, dt)[1:-1], dp[1:-1], atol=1e-3)


@pytest.mark.parametrize("ratio", [0.5, 1.0, 2.0, 5.0])
def test_zero_phase_highpass_has_the_butterworth_magnitude_squared_and_no_delay(ratio: float) -> None:
    """filtfilt of an order-n Butterworth: gain 1 / (1 + (fc/f)^2n) and zero phase, for a steady sine."""
    dt, fc, order = 0.005, 0.4, 4
    f = ratio * fc
    t = np.arange(int(400 / dt)) * dt
    x = np.sin(2 * np.pi * f * t)
    y = processing.highpass(x, dt, fc, order)
    mid = slice(len(t) // 4, 3 * len(t) // 4)  # away from the ends' transients
    gain = 1.0 / (1.0 + (fc / f) ** (2 * order))
    fit = np.linalg.lstsq(np.column_stack([np.sin(2 * np.pi * f * t[mid]), np.cos(2 * np.pi * f * t[mid])]),
                          y[mid], rcond=None)[0]
    assert fit[0] == pytest.approx(gain, rel=1e-3, abs=1e-6)
    assert abs(fit[1]) < 1e-4  # no quadrature part: zero phase


def test_upsampling_to_1khz_adds_no_images() -> None:
    dt = 0.005  # 200 Hz record
    t = np.arange(4000) * dt
    x = np.sin(2 * np.pi * 70.0 * t) * signal.windows.tukey(t.size, 0.2)
    y = processing.resample(x, dt, 1000.0)
    assert y.size == 5 * x.size
    spectrum = np.abs(np.fft.rfft(y * np.hanning(y.size)))
    freqs = np.fft.rfftfreq(y.size, 1e-3)
    assert spectrum[freqs > 100].max() < 1e-3 * spectrum.max()  # the image at 130 Hz is gone
    np.testing.assert_allclose(y[::5][400:-400], x[400:-400], atol=0.02)


def test_downsampling_to_1khz_folds_nothing_back() -> None:
    dt = 0.00025  # 4 kHz record: a 700 Hz tone would alias to 300 Hz at 1 kHz
    t = np.arange(16000) * dt
    win = signal.windows.tukey(t.size, 0.2)
    y = processing.resample((np.sin(2 * np.pi * 50 * t) + np.sin(2 * np.pi * 700 * t)) * win, dt, 1000.0)
    spectrum = np.abs(np.fft.rfft(y * np.hanning(y.size)))
    freqs = np.fft.rfftfreq(y.size, 1e-3)
    tone = spectrum[np.abs(freqs - 50) < 2].max()
    assert spectrum[np.abs(freqs - 300) < 20].max() < 1e-3 * tone
    assert np.max(np.abs(y[1000:-1000])) == pytest.approx(1.0, rel=0.01)  # the 50 Hz tone keeps its amplitude


def test_resample_ratio_is_the_simplest_fraction_within_a_microsecond_a_second() -> None:
    assert processing.resample_ratio(0.005, 1000.0) == (5, 1)
    assert processing.resample_ratio(0.0024, 1000.0) == (12, 5)
    assert processing.resample_ratio(0.00833333, 1000.0) == (25, 3)  # 120 Hz written with 6 digits
    assert processing.resample_ratio(0.00833, 1000.0) == (833, 100)  # not 1/120: 4e-4 away from 25/3
    assert processing.resample_ratio(math.pi / 1000, 1000.0) == (355, 113)  # 8.5e-8 relative
    with pytest.raises(ValueError, match="is within 1e-06 of no ratio of whole numbers"):
        processing.resample_ratio(0.001 * (1 + 2**0.5 * 1e-5), 1000.0)  # 1/1 is 1.4e-5 away, others further


def test_a_120_hz_record_written_with_six_digits_resamples_to_the_tone_it_carries() -> None:
    f = 5.0
    n = 1200
    dt_file = 0.00833333
    x = np.sin(2 * math.pi * f * np.arange(n) / 120.0)
    y = processing.resample(x, dt_file, 1000.0)
    assert len(y) == pytest.approx(n * 25 / 3, abs=2)
    t = np.arange(len(y)) / 1000.0
    np.testing.assert_allclose(y[500:-500], np.sin(2 * math.pi * f * t[500:-500]), atol=2e-3)


# --------------------------------------------------------------------------------------------------
# prepare_drive against closed forms
# --------------------------------------------------------------------------------------------------


def motion_from(acc: np.ndarray, dt: float, name: str = "burst", **extra: np.ndarray) -> GroundMotion:
    return GroundMotion(name=name, dt=dt, acc_h=acc / G, **{k: v / G for k, v in extra.items()})


def test_sine_burst_integrates_to_the_analytic_velocity_and_displacement() -> None:
    dt = 0.005
    _, disp, vel, acc = burst(0.05, 1.0, 8, dt)
    motion = motion_from(acc, dt)
    drive = prepare_drive(motion)
    assert drive.scale_factor == 1.0
    assert not drive.governing.binding
    for exact, prepared in ((disp, drive.poses[:, 0]), (vel, drive.velocities[:, 0])):
        got = at_record_times(drive, motion, prepared)
        assert np.max(np.abs(got - exact)) < 0.01 * np.max(np.abs(exact))
    assert_starts_and_ends_home(drive)


def test_scale_factor_of_a_burst_with_known_peaks_is_the_hand_value() -> None:
    """Peaks from the closed form on a fine grid; the scale by hand is min(limit / peak) over quantities."""
    dt = 0.005
    _, disp_f, vel_f, acc_f = burst(0.12, 1.2, 8, 0.0001)
    hand = {"displacement": 0.25 / np.abs(disp_f).max(), "velocity": 0.5 / np.abs(vel_f).max(),
            "acceleration": 0.6 * G / np.abs(acc_f).max()}
    quantity = min(hand, key=hand.get)
    _, _, _, acc = burst(0.12, 1.2, 8, dt)
    drive = prepare_drive(motion_from(acc, dt))
    assert drive.governing.axis == "surge"
    assert drive.governing.quantity == quantity == "velocity"
    assert drive.governing.binding
    assert drive.scale_factor == pytest.approx(hand[quantity], rel=0.01)
    assert drive.peaks["surge"]["velocity"] == pytest.approx(0.5, rel=1e-9)


def test_acceleration_governs_a_short_period_burst() -> None:
    dt = 0.005
    _, _, _, acc = burst(0.004, 8.0, 40, dt)  # 8 Hz: a = D ω² ≈ 10 m/s² > 0.6 g, tiny displacement
    drive = prepare_drive(motion_from(acc, dt))
    assert (drive.governing.quantity, drive.governing.binding) == ("acceleration", True)
    assert drive.scale_factor == pytest.approx(0.6 * G / drive.governing.peak, rel=1e-12)
    assert drive.peaks["surge"]["acceleration"] == pytest.approx(0.6 * G, rel=1e-9)


def test_a_record_far_inside_the_limits_keeps_scale_one_and_the_lowest_corner() -> None:
    dt = 0.01
    rng = np.random.default_rng(3)
    acc = signal.sosfiltfilt(signal.butter(4, [0.5, 10], "bandpass", fs=100, output="sos"),
                             rng.normal(size=3000)) * 0.05
    drive = prepare_drive(motion_from(acc, dt))
    assert drive.scale_factor == 1.0
    assert drive.corner_frequency == pytest.approx(FC_MIN)
    assert all(v < 0.5 * getattr(TABLE_IV.surge, q) for q, v in drive.peaks["surge"].items())


def test_a_long_period_pulse_is_fitted_by_the_high_pass_not_by_the_scale() -> None:
    """A 0.1 Hz, 2 m displacement pulse: the corner rises until velocity or acceleration governs."""
    dt = 0.01
    _, _, _, acc = burst(2.0, 0.1, 2, dt, quiet=5.0)
    _, _, _, acc_hf = burst(0.01, 3.0, 30, dt, quiet=5.0 + 3.0)
    n = min(acc.size, acc_hf.size)
    motion = motion_from(acc[:n] + acc_hf[:n], dt)
    at_lowest = prepare_drive(motion, corner=FC_MIN)
    assert (at_lowest.governing.quantity, at_lowest.governing.binding) == ("displacement", True)
    drive = prepare_drive(motion)
    assert drive.corner_frequency > FC_MIN
    assert drive.scale_factor > at_lowest.scale_factor
    assert drive.governing.quantity != "displacement" or not drive.governing.binding


def test_bidirectional_record_with_vertical_drives_three_axes_with_one_scale() -> None:
    dt = 0.005
    _, _, _, a1 = burst(0.05, 1.0, 8, dt)
    _, _, _, a2 = burst(0.03, 1.5, 8, dt)
    _, _, _, av = burst(0.004, 6.0, 40, dt)
    n = min(a1.size, a2.size, av.size)
    motion = motion_from(a1[:n], dt, acc_h2=a2[:n], acc_v=av[:n] * 3.0)
    drive = prepare_drive(motion)
    assert drive.components == ("surge", "lateral", "heave")
    assert drive.governing.axis == "heave" and drive.governing.quantity == "acceleration"
    assert drive.scale_factor == pytest.approx(0.7 * G / drive.governing.peak, rel=1e-12)
    alone = prepare_drive(motion_from(a1[:n], dt), corner=drive.corner_frequency)
    ratio = drive.peaks["surge"]["acceleration"] / alone.peaks["surge"]["acceleration"]
    assert ratio == pytest.approx(drive.scale_factor, rel=1e-6)  # one factor for every component
    assert_inside_limits(drive)


def test_drive_timeline_tilt_ramps_and_rest_at_both_ends() -> None:
    dt = 0.005
    _, _, _, acc = burst(0.05, 1.0, 8, dt)
    beta = math.radians(7.0)
    drive = prepare_drive(motion_from(acc, dt), angle=beta)
    assert drive.rate == 1000.0
    np.testing.assert_allclose(np.diff(drive.t), 1e-3, rtol=1e-9)
    pitch = drive.poses[:, 4]
    start, end = drive.motion
    during = (drive.t >= start) & (drive.t <= end)
    np.testing.assert_allclose(pitch[during], beta)
    assert_starts_and_ends_home(drive)
    tilt_limits = TABLE_IV.tilt
    rate = np.gradient(pitch, drive.t)
    accel = np.gradient(rate, drive.t)
    jerk = np.gradient(accel, drive.t)
    assert np.abs(rate).max() <= tilt_limits.rate * 1.001
    assert np.abs(accel).max() <= tilt_limits.acceleration * 1.01
    assert np.abs(jerk).max() <= tilt_limits.jerk * 1.05
    np.testing.assert_allclose(rate, drive.velocities[:, 4], atol=tilt_limits.rate * 2e-3)
    assert np.all(drive.poses[drive.t < start, :3] == 0.0)  # the plate tilts before it moves


def test_a_drive_for_a_table_already_tilted_starts_and_ends_at_the_tilt() -> None:
    """``ramps=False``: the same motion, without the ramps — shorter by both ramps, pitch β throughout, the
    translations identical to the ramped drive's over the motion, at rest at both ends."""
    dt = 0.005
    _, _, _, acc = burst(0.05, 1.0, 8, dt)
    beta = math.radians(5.0)
    ramped = prepare_drive(motion_from(acc, dt), angle=beta)
    tilted = prepare_drive(motion_from(acc, dt), angle=beta, ramps=False)
    n_ramp = round(tilt.ramp_duration(beta, TABLE_IV.tilt, 1000.0) * 1000)
    assert len(tilted.t) == len(ramped.t) - 2 * n_ramp
    np.testing.assert_array_equal(tilted.poses[:, 4], beta)
    np.testing.assert_array_equal(tilted.poses[:, :3], ramped.poses[n_ramp:len(ramped.t) - n_ramp, :3])
    assert tilted.scale_factor == ramped.scale_factor
    assert np.all(tilted.poses[[0, -1], :3] == 0.0) and np.all(tilted.velocities[[0, -1]] == 0.0)
    assert tilted.motion[0] == pytest.approx(ramped.motion[0] - n_ramp / 1000)


def test_ramp_duration_is_set_by_the_binding_tilt_limit() -> None:
    limits = TABLE_IV.tilt
    change = math.radians(7.0)
    duration = tilt.ramp_duration(change, limits, 1000.0)
    angle, speed, accel = tilt.ramp(0.0, change, duration, 1000.0)
    peaks = (np.abs(speed).max() / limits.rate, np.abs(accel).max() / limits.acceleration)
    assert max(peaks) == pytest.approx(1.0, rel=2e-3)  # the shortest ramp touches one limit
    assert angle[0] == 0.0 and angle[-1] == pytest.approx(change, rel=1e-5)


def test_velocity_and_acceleration_are_the_derivatives_of_the_displacement() -> None:
    motion = load_records("fema-farfield")[0]
    drive = prepare_drive(motion, angle=math.radians(5))
    fd_v = np.gradient(drive.poses[:, 0], drive.t)
    fd_a = np.gradient(drive.velocities[:, 0], drive.t)
    assert np.max(np.abs(fd_v - drive.velocities[:, 0])) < 2e-3 * np.max(np.abs(drive.velocities[:, 0]))
    assert np.max(np.abs(fd_a - drive.accelerations[:, 0])) < 2e-2 * np.max(np.abs(drive.accelerations[:, 0]))


# --------------------------------------------------------------------------------------------------
# every FEMA component, and generated records
# --------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def fema_records() -> list[GroundMotion]:
    return load_records("fema")


@pytest.mark.parametrize("angle_deg", [0.0, 7.0])
def test_every_fema_drive_lies_inside_table_iv_and_every_leg(fema_records, angle_deg: float) -> None:
    table = TableModel()
    governing = set()
    for motion in fema_records:
        drive = prepare_drive(motion, angle=math.radians(angle_deg), table=table)  # raises if a leg is exceeded
        assert 0.0 < drive.scale_factor <= 1.0
        assert_inside_limits(drive)
        assert_starts_and_ends_home(drive)
        lengths = table.leg_lengths(drive.poses)
        assert lengths.min() >= table.geometry.leg_min and lengths.max() <= table.geometry.leg_max
        speeds = np.abs(np.gradient(lengths, drive.t, axis=0))
        assert speeds.max() <= table.geometry.leg_speed
        governing.add(drive.governing.quantity)
    assert len(fema_records) == 100
    assert {"velocity", "acceleration"} <= governing  # the suite exercises more than one limit


@st.composite
def generated_records(draw) -> GroundMotion:
    dt = draw(st.sampled_from([0.005, 0.01, 0.02, 0.0025]))
    seconds = draw(st.floats(3.0, 40.0))
    n = int(seconds / dt)
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    fs = 1.0 / dt
    band = draw(st.tuples(st.floats(0.02, 1.0), st.floats(2.0, 0.4 * fs)))
    sos = signal.butter(2, band, "bandpass", fs=fs, output="sos")
    channels = {}
    for name in ("acc_h", "acc_h2", "acc_v"):
        if name == "acc_h" or draw(st.booleans()):
            x = signal.sosfilt(sos, rng.normal(size=n))
            channels[name] = x / np.abs(x).max() * draw(st.floats(0.005, 3.0))
    if draw(st.booleans()):  # a baseline offset and drift, as a real sensor has
        channels["acc_h"] = channels["acc_h"] + draw(st.floats(-0.05, 0.05)) + np.linspace(0, 0.02, n)
    return GroundMotion(name=f"generated-{seed}", dt=dt, **channels)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(motion=generated_records(), angle_deg=st.sampled_from([0.0, 4.0, 7.0]))
def test_generated_records_give_drives_inside_every_limit(motion: GroundMotion, angle_deg: float) -> None:
    drive = prepare_drive(motion, angle=math.radians(angle_deg))
    assert 0.0 < drive.scale_factor <= 1.0
    assert_inside_limits(drive)
    assert_starts_and_ends_home(drive)
    assert drive.t.size == drive.poses.shape[0]


# --------------------------------------------------------------------------------------------------
# refusals and options
# --------------------------------------------------------------------------------------------------


def test_a_drive_beyond_the_legs_is_refused_with_the_first_violation() -> None:
    default = HexapodGeometry.default()
    short = HexapodGeometry(default.base_joints, default.platform_joints, default.home_height,
                            default.leg_min, default.leg_min + 0.55 * (default.leg_max - default.leg_min),
                            default.leg_speed)
    table = TableModel(geometry=short)
    motion = load_records("fema-farfield")[0]
    with pytest.raises(DriveRefusedError) as info:
        prepare_drive(motion, angle=math.radians(7), table=table)
    violation = info.value.violation
    assert violation.where.startswith("leg ") and violation.quantity == "stroke"
    assert violation.value > violation.limit == pytest.approx(short.leg_max)
    assert f"{violation.time:.3f}" in str(info.value)
    # nothing before the reported time breaks the stroke: it is the first violation
    drive_ok = prepare_drive(motion, angle=math.radians(7))
    lengths = table.leg_lengths(drive_ok.poses)
    first = np.flatnonzero(lengths.max(axis=1) > short.leg_max * (1 + 1e-9))[0]
    assert drive_ok.t[first] == pytest.approx(violation.time)


def test_options_out_of_range_are_refused_clearly() -> None:
    motion = load_records("fema-farfield")[0]
    with pytest.raises(DriveError, match=r"angle 12° is beyond the table's tilt limit ±10°"):
        prepare_drive(motion, angle=math.radians(12))
    largest = prepare_drive(motion).scale_factor
    with pytest.raises(DriveError, match="scale factor 1 is outside"):
        prepare_drive(motion, scale=1.0) if largest < 1.0 else prepare_drive(motion, scale=1.5)
    fixed = prepare_drive(motion, scale=0.5 * largest)
    assert fixed.scale_factor == 0.5 * largest
    with pytest.raises(DriveError, match="corner frequency 90 Hz must lie in"):
        prepare_drive(motion, corner=90.0)


def test_tighter_rig_limits_lower_the_scale_factor() -> None:
    motion = load_records("fema-farfield")[0]
    half = AxisLimits(0.125, 0.25, 0.3 * G)
    limits = TableLimits(half, half, TABLE_IV.heave, TABLE_IV.tilt)
    wide = prepare_drive(motion)
    tight = prepare_drive(motion, table=TableModel(limits=limits), corner=wide.corner_frequency)
    assert tight.scale_factor == pytest.approx(0.5 * wide.scale_factor, rel=1e-9)


# --------------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------------

runner = CliRunner()


def test_cli_prepare_json_has_the_architecture_fields(tmp_path: Path) -> None:
    png = tmp_path / "drive.png"
    result = runner.invoke(app, ["prepare", "fema:NORTHR/MUL009", "--angle", "5", "--json", "--plot", str(png)])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert 0 < out["scale_factor"] <= 1
    assert out["governing"]["axis"] == "surge" and out["governing"]["quantity"] in ("velocity", "acceleration",
                                                                                     "displacement")
    assert set(out["peaks"]) == {"surge", "lateral", "heave"}
    assert out["peaks"]["surge"]["acceleration"] <= 0.6 + 1e-9  # g
    assert out["angle_deg"] == 5 and out["duration"] > 0 and out["rate_hz"] == 1000
    assert png.stat().st_size > 20_000


def test_cli_prepare_errors_exit_2_and_refusals_exit_3(tmp_path: Path) -> None:
    result = runner.invoke(app, ["prepare", "fema:NO/SUCH", "--json"])
    assert result.exit_code == 2 and "error:" in result.stderr and result.stdout == ""
    result = runner.invoke(app, ["prepare", "fema:NORTHR/MUL009", "--angle", "30"])
    assert result.exit_code == 2 and "tilt limit" in result.stderr
    config = tmp_path / "short.toml"
    g = HexapodGeometry.default()
    config.write_text(
        "[hexapod]\n"
        f"base_joints_m = {g.base_joints.tolist()}\nplatform_joints_m = {g.platform_joints.tolist()}\n"
        f"home_height_m = {g.home_height}\nleg_min_m = {g.leg_min}\n"
        f"leg_max_m = {g.leg_min + 0.55 * (g.leg_max - g.leg_min)}\nleg_speed_m_s = {g.leg_speed}\n"
    )
    result = runner.invoke(app, ["prepare", "fema:NORTHR/MUL009", "--angle", "7", "--rig-config", str(config),
                                 "--json"])
    assert result.exit_code == 3, result.output
    refused = json.loads(result.stdout)["refused"]
    assert refused["quantity"] == "stroke" and refused["where"].startswith("leg ")
    assert "refused" in result.stderr
