"""The table model: Table IV, the hexapod's kinematics against hand computations, the default geometry's
workspace and leg speeds, the trajectory check and the rig configuration file."""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

from analysis.body import G
from analysis.errors import AnalysisInputError
from analysis.table.model import (
    AXES,
    TABLE_IV,
    AxisLimits,
    HexapodGeometry,
    TableLimits,
    TableModel,
    TableModelError,
    TiltLimits,
    Violation,
    rotation_matrices,
)

MODEL = TableModel()
GEOMETRY = MODEL.geometry
DEG = math.pi / 180
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "rig-table4.toml"
SOME = settings(max_examples=60, deadline=None)

# the default layout as documented: radii, half angles, joint depth, home height
RB, RP, HALF, DEPTH, HOME = 1.6, 1.1, 10 * DEG, 0.15, 2.1
WORKSPACE = np.array([0.25, 0.25, 0.18, 10 * DEG, 10 * DEG, 0.0])  # Table IV box × 10° tilt, yaw 0
MIRROR = [1, 0, 5, 4, 3, 2]  # legs under y → −y


def grid_and_sample(n: int, seed: int) -> np.ndarray:
    """The workspace's 3^5 grid (all corners, edge and face centres) and ``n`` uniform random poses."""
    grid = np.array(list(itertools.product(*[[-1.0, 0.0, 1.0]] * 5 + [[0.0]])))
    sample = np.random.default_rng(seed).uniform(-1, 1, (n, 6))
    return np.concatenate([grid, sample]) * WORKSPACE


def pose(surge=0.0, sway=0.0, heave=0.0, roll=0.0, pitch=0.0, yaw=0.0) -> np.ndarray:
    return np.array([surge, sway, heave, roll, pitch, yaw])


# ----- Table IV ------------------------------------------------------------------------------------------


def test_table_iv_as_printed_in_si() -> None:
    for name, (d, v, a) in {"surge": (0.25, 0.5, 0.6), "lateral": (0.25, 0.5, 0.6), "heave": (0.18, 0.3, 0.7)}.items():
        assert TABLE_IV.axis(name) == AxisLimits(displacement=d, velocity=v, acceleration=a * 9.81)
    assert TABLE_IV.tilt == TiltLimits(angle=math.radians(10), rate=math.radians(2), acceleration=math.radians(2),
                                       jerk=math.radians(4))
    assert AXES == ("surge", "lateral", "heave")


def test_limits_reject_bad_values_and_names() -> None:
    with pytest.raises(TableModelError, match=r"^AxisLimits.velocity: must be a finite number > 0, got -0.5$"):
        AxisLimits(displacement=0.25, velocity=-0.5, acceleration=5.0)
    with pytest.raises(TableModelError, match=r"^TiltLimits.angle: expected a number, got '10'$"):
        TiltLimits(angle="10")
    with pytest.raises(TableModelError, match=r"^unknown axis 'sway': expected one of surge, lateral, heave$"):
        TABLE_IV.axis("sway")
    with pytest.raises(TableModelError, match=r"did you mean 'heave'\?"):
        TABLE_IV.axis("heav")


# ----- kinematics against hand computations ------------------------------------------------------------------


def test_rotation_order_and_the_tilt_sign() -> None:
    roll, pitch, yaw = 0.3, -0.2, 1.1
    rx = np.array([[1, 0, 0], [0, math.cos(roll), -math.sin(roll)], [0, math.sin(roll), math.cos(roll)]])
    ry = np.array([[math.cos(pitch), 0, math.sin(pitch)], [0, 1, 0], [-math.sin(pitch), 0, math.cos(pitch)]])
    rz = np.array([[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]])
    np.testing.assert_allclose(rotation_matrices(pose(roll=roll, pitch=pitch, yaw=yaw)), rz @ ry @ rx, atol=1e-15)
    beta = 5 * DEG  # pitch = +β takes the plate's +x end down: +x is downhill
    assert (rotation_matrices(pose(pitch=beta)) @ [1.0, 0.0, 0.0])[2] == pytest.approx(-math.sin(beta))


@pytest.mark.parametrize("heave", [-0.18, 0.0, 0.1, 0.18])
def test_pure_heave_leg_lengths_by_hand(heave: float) -> None:
    """Every leg joins a base joint at azimuth −10° (+120° k) to a platform joint at −50°: horizontal
    distance by the law of cosines over the 40° between them, vertical = home height − depth + heave."""
    horizontal2 = RB**2 + RP**2 - 2 * RB * RP * math.cos(math.radians(40))
    expected = math.sqrt(horizontal2 + (HOME - DEPTH + heave) ** 2)
    np.testing.assert_allclose(MODEL.leg_lengths(pose(heave=heave)), expected, rtol=0, atol=1e-14)


@pytest.mark.parametrize("yaw_deg", [-15.0, -4.0, 3.0, 20.0])
def test_pure_yaw_by_hand_and_by_symmetry(yaw_deg: float) -> None:
    yaw = math.radians(yaw_deg)
    lengths = MODEL.leg_lengths(pose(yaw=yaw))
    vertical2 = (HOME - DEPTH) ** 2  # leg 1: base joint at −10°, platform joint at −50° turned by the yaw
    assert lengths[0] == pytest.approx(math.sqrt(RB**2 + RP**2 - 2 * RB * RP * math.cos(yaw - math.radians(40))
                                                 + vertical2), abs=1e-14)
    assert lengths[1] == pytest.approx(math.sqrt(RB**2 + RP**2 - 2 * RB * RP * math.cos(yaw + math.radians(40))
                                                 + vertical2), abs=1e-14)
    np.testing.assert_allclose(lengths[[0, 2, 4]], lengths[0], atol=1e-14)  # 3-fold symmetry
    np.testing.assert_allclose(lengths[[1, 3, 5]], lengths[1], atol=1e-14)
    np.testing.assert_allclose(MODEL.leg_lengths(pose(yaw=-yaw)), lengths[MIRROR], atol=1e-14)
    assert (lengths[0] > lengths[1]) == (yaw < 0)


finite = st.floats(-1.0, 1.0)


@SOME
@given(st.tuples(*[finite] * 6))
def test_three_fold_and_mirror_symmetry(unit: tuple[float, ...]) -> None:
    """Turning a translation + yaw pose by 120° about z moves every leg's length to leg k + 2; the mirror
    y → −y maps (x, y, z, roll, pitch, yaw) to (x, −y, z, −roll, pitch, −yaw) and legs 1↔2, 3↔6, 4↔5."""
    p = np.array(unit) * np.array([0.25, 0.25, 0.18, 0.2, 0.2, 0.5])
    lengths = MODEL.leg_lengths(p)
    c, s = math.cos(2 * math.pi / 3), math.sin(2 * math.pi / 3)
    turned = pose(c * p[0] - s * p[1], s * p[0] + c * p[1], p[2], yaw=p[5])
    np.testing.assert_allclose(MODEL.leg_lengths(turned), np.roll(MODEL.leg_lengths(pose(*p[:3], yaw=p[5])), 2),
                               atol=1e-13)
    mirrored = p * np.array([1, -1, 1, -1, 1, -1])
    np.testing.assert_allclose(MODEL.leg_lengths(mirrored), lengths[MIRROR], atol=1e-13)


@SOME
@given(st.tuples(*[finite] * 6), st.tuples(*[finite] * 6))
def test_jacobian_matches_finite_differences(unit: tuple[float, ...], rates: tuple[float, ...]) -> None:
    p = np.array(unit) * np.array([0.25, 0.25, 0.18, 0.2, 0.2, 1.0])
    h = 1e-6
    columns = [(MODEL.leg_lengths(p + h * e) - MODEL.leg_lengths(p - h * e)) / (2 * h) for e in np.eye(6)]
    np.testing.assert_allclose(MODEL.leg_jacobian(p), np.stack(columns, axis=-1), atol=1e-8)
    v = np.array(rates)
    np.testing.assert_allclose(MODEL.leg_velocities(p, v), np.stack(columns, axis=-1) @ v, atol=1e-7)


def test_ik_is_vectorised_over_any_leading_shape() -> None:
    poses = grid_and_sample(57, seed=1)[:300].reshape(3, 100, 6)
    lengths = MODEL.leg_lengths(poses)
    assert lengths.shape == (3, 100, 6)
    np.testing.assert_allclose(lengths[2, 7], MODEL.leg_lengths(poses[2, 7]), rtol=0, atol=1e-14)
    assert MODEL.leg_jacobian(poses).shape == (3, 100, 6, 6)
    with pytest.raises(AnalysisInputError, match=r"^poses: expected an array of shape \(\.\.\., 6\), got shape \(4, 5"):
        MODEL.leg_lengths(np.zeros((4, 5)))


# ----- forward kinematics ------------------------------------------------------------------------------------


def test_fk_round_trip_over_the_workspace() -> None:
    poses = grid_and_sample(1500, seed=7)
    poses[243:, 5] = np.random.default_rng(8).uniform(-5, 5, len(poses) - 243) * DEG  # some yaw as well
    lengths = MODEL.leg_lengths(poses)
    found = MODEL.pose_from_leg_lengths(lengths)
    assert np.max(np.abs(found - poses)) < 1e-9
    assert np.max(np.abs(MODEL.leg_lengths(found) - lengths)) < 1e-9


@SOME
@given(st.tuples(*[finite] * 6))
def test_fk_round_trip_single_pose_from_a_guess(unit: tuple[float, ...]) -> None:
    p = np.array(unit) * np.array([0.25, 0.25, 0.18, 10 * DEG, 10 * DEG, 10 * DEG])
    found = MODEL.pose_from_leg_lengths(MODEL.leg_lengths(p), guess=0.9 * p)
    assert np.max(np.abs(found - p)) < 1e-9


def test_fk_reports_non_convergence_and_bad_lengths() -> None:
    far = MODEL.leg_lengths(pose(0.25, -0.25, 0.18, 10 * DEG, -10 * DEG))
    expected = (r"^forward kinematics did not converge in 1 Newton iterations: largest leg-length residual "
                r"\d\.\d{3}e-\d\d m \(tolerance 1\.0e-12 m\)$")
    with pytest.raises(TableModelError, match=expected):
        MODEL.pose_from_leg_lengths(far, max_iter=1)
    with pytest.raises(AnalysisInputError, match="leg lengths must be > 0 m"):
        MODEL.pose_from_leg_lengths(np.array([2.2, 2.2, 0.0, 2.2, 2.2, 2.2]))


# ----- the default geometry ----------------------------------------------------------------------------------


def stroke_margin(poses: np.ndarray) -> float:
    """The smallest distance [m] of any leg of any pose to either end of the stroke (< 0: outside)."""
    lengths = MODEL.leg_lengths(poses)
    return float(min(np.min(lengths - GEOMETRY.leg_min), np.min(GEOMETRY.leg_max - lengths)))


def test_default_geometry_is_the_documented_symmetric_layout() -> None:
    documented = HexapodGeometry.symmetric(RB, RP, HALF, HALF, HOME, 1.6, 2.85, 0.9, platform_joint_depth=DEPTH)
    assert documented == GEOMETRY
    np.testing.assert_allclose(np.hypot(GEOMETRY.base_joints[:, 0], GEOMETRY.base_joints[:, 1]), RB)
    np.testing.assert_allclose(GEOMETRY.platform_joints[:, 2], -DEPTH)
    assert not GEOMETRY.base_joints.flags.writeable
    assert hash(TableModel()) == hash(MODEL)


@pytest.mark.parametrize("name", AXES)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_default_geometry_reaches_each_table_iv_axis_limit(name: str, sign: float) -> None:
    p = np.zeros(6)
    p[AXES.index(name)] = sign * TABLE_IV.axis(name).displacement
    assert stroke_margin(p) > 0.2


@pytest.mark.parametrize("column", [3, 4])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_default_geometry_reaches_a_7_degree_tilt(column: int, sign: float) -> None:
    p = np.zeros(6)
    p[column] = sign * 7 * DEG
    assert stroke_margin(p) > 0.3


def test_default_geometry_plays_the_table_iv_box_combined_with_a_10_degree_tilt() -> None:
    """Corners, edges and faces of the box × ±10° roll and pitch, and random poses inside: ≥ 0.05 m of
    stroke left at both ends (the docstring's 0.070 m, found at corners)."""
    assert stroke_margin(grid_and_sample(20000, seed=3)) == pytest.approx(0.0702, abs=5e-4)


def test_default_leg_speed_covers_table_iv_velocities_with_tilt_rate() -> None:
    """The worst leg rate over all velocity combinations inside Table IV (|vx|, |vy| ≤ 0.5, |vz| ≤ 0.3 m/s)
    plus 2°/s of roll and pitch is Σ_j |J_kj| v_j (a linear function is largest at a corner of the box),
    taken over poses across the workspace; it stays within leg_speed."""
    velocity_box = np.array([0.5, 0.5, 0.3, 2 * DEG, 2 * DEG, 0.0])
    worst = np.max(np.abs(MODEL.leg_jacobian(grid_and_sample(5000, seed=5))) @ velocity_box)
    assert 0.7 < worst < GEOMETRY.leg_speed - 0.15
    corner = grid_and_sample(0, seed=0)[-1]  # (+0.25, +0.25, +0.18, +10°, +10°) with every rate at +its limit
    speeds = MODEL.leg_velocities(np.stack([corner, corner]), np.stack([velocity_box, -velocity_box]))
    assert np.max(np.abs(speeds)) <= worst


def test_geometry_validation() -> None:
    with pytest.raises(TableModelError, match=r"^HexapodGeometry.leg_max: must exceed leg_min \(2.9 m\), got 2.85 m$"):
        dataclasses.replace(GEOMETRY, leg_min=2.9)
    with pytest.raises(TableModelError, match=r"^HexapodGeometry.home_height: the home pose is outside the stroke: "
                                              r"leg 1 length 2.2082 m is not in \[1.6000, 2.2000\] m$"):
        dataclasses.replace(GEOMETRY, leg_max=2.2)
    with pytest.raises(TableModelError, match=r"^HexapodGeometry.base_joints: expected 6 finite rows \[x, y, z\] in "
                                              r"metres, got shape \(5, 3\)$"):
        dataclasses.replace(GEOMETRY, base_joints=GEOMETRY.base_joints[:5])
    with pytest.raises(TableModelError, match="the legs are singular at home"):
        dataclasses.replace(GEOMETRY, platform_joints=np.tile([0.0, 0.0, 0.0], (6, 1)))
    with pytest.raises(TableModelError, match=r"^HexapodGeometry.symmetric: base_half_angle: must be at least 0"):
        HexapodGeometry.symmetric(RB, RP, math.pi / 3, HALF, HOME, 1.6, 2.85, 0.9)


# ----- check_trajectory --------------------------------------------------------------------------------------


def with_geometry(**changes: float) -> TableModel:
    return TableModel(geometry=dataclasses.replace(GEOMETRY, **changes))


def test_a_small_sine_motion_passes() -> None:
    t = np.arange(0.0, 10.0, 1e-3)
    w = 2 * math.pi * 0.5
    poses = np.zeros((t.size, 6))
    poses[:, 0] = 0.1 * np.sin(w * t)
    poses[:, 1] = 0.05 * np.sin(2 * w * t)
    poses[:, 2] = 0.02 * np.sin(3 * w * t)
    poses[:, 4] = 5 * DEG
    assert MODEL.check_trajectory(t, poses) is None


@pytest.mark.parametrize(("direction", "changes", "bound"), [
    ((-1, -1, 1, -10, -10), {"leg_max": 2.6}, "leg_max"),   # leg 1's longest corner
    ((1, 1, -1, 10, 10), {"leg_min": 1.8}, "leg_min"),      # leg 1's shortest corner
])
def test_first_stroke_violation_at_the_known_instant(direction, changes, bound) -> None:
    """A slow straight line from home to a workspace corner: leg 1 crosses the (lowered/raised) bound at
    the root of its length; the check names the first sample past it."""
    model = with_geometry(**changes)
    corner = np.array([*direction, 0.0]) * np.array([0.25, 0.25, 0.18, DEG, DEG, 0.0])
    t = np.linspace(0.0, 100.0, 10001)
    poses = t[:, None] / 100.0 * corner
    limit = changes[bound]
    crossing = brentq(lambda s: MODEL.leg_lengths(s / 100.0 * corner)[0] - limit, 0.0, 100.0, xtol=1e-12)
    expected = t[np.searchsorted(t, crossing, side="right")]
    v = model.check_trajectory(t, poses)
    assert (v.where, v.quantity, v.limit, v.time) == ("leg 1", "stroke", limit, expected)
    assert v.value == pytest.approx(MODEL.leg_lengths(poses[t == expected][0])[0], abs=1e-13)
    assert 0 < abs(v.value - limit) < 2e-4


def pure_heave_leg_rate(z: float, vz: float) -> float:
    vertical = HOME - DEPTH + z
    horizontal2 = RB**2 + RP**2 - 2 * RB * RP * math.cos(math.radians(40))
    return vertical * vz / math.sqrt(horizontal2 + vertical**2)


def test_first_leg_speed_violation() -> None:
    """Heave at constant acceleration a: all legs lengthen at (H + z) ż / L (by hand); all six cross a
    lowered leg_speed at the same sample, and leg 1 is reported (ties by index)."""
    model, a = with_geometry(leg_speed=0.2), 0.5
    t = np.arange(0.0, 1.0, 1e-3)
    poses, velocities = np.zeros((t.size, 6)), np.zeros((t.size, 6))
    poses[:, 2], velocities[:, 2] = 0.5 * a * t**2, a * t
    crossing = brentq(lambda s: pure_heave_leg_rate(0.5 * a * s**2, a * s) - 0.2, 0.0, 1.0, xtol=1e-12)
    i = np.searchsorted(t, crossing, side="right")
    v = model.check_trajectory(t, poses, velocities)
    assert (v.where, v.quantity, v.time, v.limit) == ("leg 1", "speed", t[i], 0.2)
    assert v.value == pytest.approx(pure_heave_leg_rate(poses[i, 2], velocities[i, 2]), abs=1e-12)
    by_gradient = model.check_trajectory(t, poses)  # without velocities: np.gradient of the leg lengths
    assert (by_gradient.where, by_gradient.quantity) == ("leg 1", "speed")
    assert abs(by_gradient.time - t[i]) <= 1e-3 + 1e-12


def _surge_sine(amplitude: float, w: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """0.2 s at 10 kHz of a surge sine ``amplitude`` [m] at ``w`` [rad/s]: times, poses, velocities, accelerations."""
    t = np.arange(0.0, 0.2, 1e-4)
    poses, velocities, accelerations = (np.zeros((t.size, 6)) for _ in range(3))
    poses[:, 0] = amplitude * np.sin(w * t)
    velocities[:, 0] = amplitude * w * np.cos(w * t)
    accelerations[:, 0] = -amplitude * w**2 * np.sin(w * t)
    return t, poses, velocities, accelerations


@pytest.mark.parametrize("given_derivatives", [True, False])
def test_first_surge_acceleration_violation(given_derivatives: bool) -> None:
    """5 Hz surge sine of 7 mm: peak acceleration 6.9 m/s² > 0.6 g; displacement and velocity are fine."""
    amplitude, w = 0.007, 2 * math.pi * 5
    t, poses, velocities, accelerations = _surge_sine(amplitude, w)
    crossing = math.asin(0.6 * G / (amplitude * w**2)) / w
    i = np.searchsorted(t, crossing, side="right")
    if given_derivatives:
        v = MODEL.check_trajectory(t, poses, velocities, accelerations)
        assert v == Violation(time=t[i], where="surge", quantity="acceleration", value=accelerations[i, 0],
                              limit=0.6 * G)
    else:
        v = MODEL.check_trajectory(t, poses)
        assert (v.where, v.quantity, v.limit) == ("surge", "acceleration", 0.6 * G)
        assert abs(v.time - t[i]) <= 2e-4 and v.value < -0.6 * G


def test_a_command_is_held_to_the_envelope_and_the_legs_not_to_table_iv_accelerations() -> None:
    """``check_command``: the 5 Hz surge sine of 7 mm (6.9 m/s² > 0.6 g, 0.22 m/s) passes — nothing in the table
    limits a command's acceleration; a 0.3 m surge excursion leaves the ±0.25 m envelope the controller clips to,
    at the first sample past it; 1.1 m/s of heave (Table IV's 0.3 m/s, but the legs' 0.9 m/s) is refused for the
    legs, not the axis."""
    amplitude, w = 0.007, 2 * math.pi * 5
    t, poses, velocities, accelerations = _surge_sine(amplitude, w)
    assert MODEL.check_trajectory(t, poses, velocities, accelerations).quantity == "acceleration"
    assert MODEL.check_command(t, poses, velocities, accelerations) is None
    far = np.zeros((t.size, 6))
    far[:, 0] = 0.3 * t / t[-1]
    i = np.searchsorted(far[:, 0], 0.25 * (1 + 1e-9), side="right")
    v = MODEL.check_command(t, far)
    assert (v.time, v.where, v.quantity, v.value, v.limit) == (t[i], "surge", "displacement", far[i, 0], 0.25)
    fast = np.zeros((t.size, 6))
    fast[:, 2] = 1.1 * t
    v = MODEL.check_command(t, fast, np.gradient(fast, t, axis=0))
    assert (v.where, v.quantity, v.limit) == ("leg 1", "speed", MODEL.geometry.leg_speed)
    assert MODEL.check_trajectory(t, fast, np.gradient(fast, t, axis=0)).where == "leg 1"  # legs before axes


def test_first_tilt_angle_violation_and_the_tolerance() -> None:
    """Pitch ramps 0 → 12° over 60 s: 10° (1 + 1e-10) at t = 50 s does not count, the next sample does."""
    t = np.linspace(0.0, 60.0, 6001)
    poses = np.zeros((t.size, 6))
    poses[:, 4] = t / 60.0 * 12 * DEG
    poses[5000, 4] = 10 * DEG * (1 + 1e-10)  # within rtol = 1e-9 of the limit
    v = MODEL.check_trajectory(t, poses)
    assert (v.time, v.where, v.quantity, v.value, v.limit) == (t[5001], "pitch", "angle", poses[5001, 4], 10 * DEG)
    poses[:, 3], poses[:, 4] = -poses[:, 4], 0.0  # the same downwards, on roll
    v = MODEL.check_trajectory(t, poses)
    assert (v.time, v.where, v.quantity, v.value, v.limit) == (t[5001], "roll", "angle", poses[5001, 3], 10 * DEG)


def test_first_tilt_rate_violation() -> None:
    """Roll ramps at 3°/s for a second after 1 s at rest: the given rate exceeds 2°/s from t = 1 s on; by
    central differences one sample later (the kink's own sample averages to 1.5°/s)."""
    t = np.linspace(0.0, 2.0, 201)
    poses, velocities = np.zeros((t.size, 6)), np.zeros((t.size, 6))
    velocities[100:, 3] = 3 * DEG
    poses[:, 3] = np.maximum(t - 1.0, 0.0) * 3 * DEG
    assert MODEL.check_trajectory(t, poses, velocities) == Violation(t[100], "roll", "rate", 3 * DEG, 2 * DEG)
    v = MODEL.check_trajectory(t, poses)
    assert (v.time, v.where, v.quantity) == (t[101], "roll", "rate")
    assert v.value == pytest.approx(3 * DEG, rel=1e-9)


def test_ties_at_one_sample_go_to_the_legs_first() -> None:
    """Heave 0.3 m exceeds the heave displacement and (with leg_max 2.4 m) every leg's stroke at t = 0."""
    poses = np.tile(pose(heave=0.3), (3, 1))
    v = with_geometry(leg_max=2.4).check_trajectory([0.0, 1.0, 2.0], poses)
    assert (v.time, v.where, v.quantity, v.limit) == (0.0, "leg 1", "stroke", 2.4)
    assert MODEL.check_trajectory([0.0, 1.0, 2.0], poses) == Violation(0.0, "heave", "displacement", 0.3, 0.18)


@pytest.mark.parametrize(("t", "poses", "message"), [
    (np.zeros((3, 2)), np.zeros((3, 6)), r"t must be a 1-D array of at least 2 times \[s\], got shape \(3, 2\)"),
    ([0.0], np.zeros((1, 6)), r"t must be a 1-D array of at least 2 times \[s\], got shape \(1,\)"),
    ([0.0, 1.0, 1.0], np.zeros((3, 6)), r"t must be strictly increasing, but t\[2\] = 1.0 s follows t\[1\] = 1.0 s"),
    ([0.0, 1.0, 2.0], np.zeros((3, 7)), r"poses must have shape \(3, 6\) to match t, got \(3, 7\)"),
    ([0.0, 1.0, 2.0], [[0.0] * 6, [0.0] * 6, [0.0, math.nan, 0, 0, 0, 0]],
     r"poses has a non-finite value at sample 2"),
    ([0.0, math.inf, 2.0], np.zeros((3, 6)), r"t has a non-finite value at sample 1"),
])
def test_check_trajectory_input_errors(t, poses, message: str) -> None:
    with pytest.raises(AnalysisInputError, match=f"^check_trajectory: {message}$"):
        MODEL.check_trajectory(t, poses)


def test_check_trajectory_derivative_shapes() -> None:
    with pytest.raises(ValueError, match=r"^check_trajectory: velocities must have shape \(3, 6\) to match t, got"):
        MODEL.check_trajectory([0.0, 1.0, 2.0], np.zeros((3, 6)), velocities=np.zeros((2, 6)))


def test_violation_messages_word_for_word() -> None:
    assert Violation(12.345, "leg 3", "stroke", 1.9123, 1.9).message() == (
        "at t = 12.345 s leg 3 length 1.9123 m exceeds the stroke limit 1.9000 m")
    assert Violation(1.5, "leg 6", "stroke", 1.5991, 1.6).message() == (
        "at t = 1.500 s leg 6 length 1.5991 m is below the stroke limit 1.6000 m")
    assert Violation(2.0, "surge", "acceleration", -6.0822, 0.6 * G).message() == (
        "at t = 2.000 s surge acceleration -6.0822 m/s² (-0.620 g) exceeds the limit ±5.8860 m/s² (0.600 g)")
    assert Violation(50.01, "pitch", "angle", 0.17471, 10 * DEG).message() == (
        "at t = 50.010 s pitch angle 0.1747 rad (10.010°) exceeds the limit ±0.1745 rad (10.000°)")
    assert Violation(0.25, "leg 1", "speed", 0.95, 0.9).message() == (
        "at t = 0.250 s leg 1 speed 0.9500 m/s exceeds the limit ±0.9000 m/s")


# ----- configuration -----------------------------------------------------------------------------------------


def test_the_example_file_is_table_iv_and_the_default_geometry() -> None:
    model = TableModel.from_toml(EXAMPLE)
    assert model.limits == TABLE_IV
    assert model.geometry == HexapodGeometry.default()
    assert model == TableModel()
    assert TableModel.from_dict({}) == model  # every section may be left out


def test_to_dict_is_json_and_from_dict_inverts_it() -> None:
    assert TableModel.from_dict(json.loads(json.dumps(MODEL.to_dict()))) == MODEL
    custom = TableModel(
        limits=TableLimits(surge=AxisLimits(0.3, 0.61, 7.1), lateral=AxisLimits(0.2, 0.4, 3.3),
                           heave=AxisLimits(0.1, 0.2, 1.23456789), tilt=TiltLimits(angle=0.123, rate=0.0456)),
        geometry=HexapodGeometry(GEOMETRY.base_joints * 1.1, GEOMETRY.platform_joints, 2.2, 1.7, 3.0, 1.25),
        controller_rate=500.0)
    assert TableModel.from_dict(json.loads(json.dumps(custom.to_dict()))) == custom
    assert TableModel.from_dict(custom.to_dict()) != MODEL


#: The documented range of each limit in SI (analysis/table/configuration.py docstring): displacement, velocity,
#: acceleration of an axis; angle, rate, acceleration, jerk of the tilt.
AXIS_RANGES = ((0.001, 2.0), (0.001, 5.0), (0.001 * G, 10 * G))
TILT_RANGES = ((0.1 * DEG, 45 * DEG), (0.01 * DEG, 90 * DEG), (0.01 * DEG, 360 * DEG), (0.01 * DEG, 3600 * DEG))


@SOME
@given(st.tuples(*(st.floats(low, high) for low, high in AXIS_RANGES * 3 + TILT_RANGES)))
def test_limits_round_trip_exactly(values: tuple[float, ...]) -> None:
    axes = [AxisLimits(*values[3 * k: 3 * k + 3]) for k in range(3)]
    model = TableModel(limits=TableLimits(*axes, tilt=TiltLimits(*values[9:13])))
    assert TableModel.from_dict(model.to_dict()) == model


def test_partial_sections_keep_table_iv_and_units_convert(tmp_path: Path) -> None:
    path = tmp_path / "rig.toml"
    path.write_text("[limits.heave]\nacceleration_m_s2 = 5\n\n[limits.tilt]\nangle_rad = 0.1\n")
    model = TableModel.from_toml(path)
    assert model.limits.heave == AxisLimits(0.18, 0.3, 5.0)
    assert model.limits.tilt == dataclasses.replace(TABLE_IV.tilt, angle=0.1)
    assert model.limits.surge == TABLE_IV.surge and model.geometry == GEOMETRY


def test_explicit_joints_in_a_file(tmp_path: Path) -> None:
    rows = ",\n  ".join(str(row) for row in GEOMETRY.base_joints.tolist())
    platform = str(GEOMETRY.platform_joints.tolist())
    path = tmp_path / "rig.toml"
    path.write_text(f"[hexapod]\nbase_joints_m = [\n  {rows}\n]\nplatform_joints_m = {platform}\n"
                    "home_height_m = 2.1\nleg_min_m = 1.6\nleg_max_m = 2.85\nleg_speed_m_s = 0.9\n")
    assert TableModel.from_toml(path).geometry == GEOMETRY
    path.write_text(path.read_text().replace("leg_max_m = 2.85", "leg_max_m = 1.5"))
    with pytest.raises(TableModelError, match=r"rig.toml:13: hexapod.leg_max_m: must exceed leg_min \(1.6 m\), got"):
        TableModel.from_toml(path)


HEXAPOD = """\
[hexapod]
base_radius_m = 1.6
platform_radius_m = 1.1
base_half_angle_deg = 10
platform_half_angle_deg = 10
home_height_m = 2.1
leg_min_m = 1.6
leg_max_m = 2.85
leg_speed_m_s = 0.9
"""


@pytest.mark.parametrize(("text", "message"), [
    ("[table]\ncontroller_rate_hz = 1000\n\n[limits.surge]\ndisplacment_m = 0.3\n",
     "rig.toml:5: limits.surge.displacment_m: unknown key (did you mean 'displacement_m'?); expected one of "
     "displacement_m, velocity_m_s, acceleration_g, acceleration_m_s2"),
    ("[limits.heave]\ndisplacement_m = 0.18\nvelocity_m_s = -0.3\n",
     "rig.toml:3: limits.heave.velocity_m_s: must be from 0.001 m/s to 5 m/s, got -0.3"),
    ("[table]\ncontroller_rate_hz = \n", "rig.toml:2: TOML syntax error: Invalid value (column 22)"),
    ("[limit.surge]\ndisplacement_m = 0.3\n",
     "rig.toml:1: limit: unknown key (did you mean 'limits'?); expected one of table, limits, hexapod, dynamics, "
     "controller, drives, sensors, limit_detectors, network"),
    ("[limits.tilt]\nangle_deg = \"10\"\n", "rig.toml:2: limits.tilt.angle_deg: expected a number, got '10'"),
    ("[limits.tilt]\nangle_deg = 10\nangle_rad = 0.2\n",
     "rig.toml:3: limits.tilt.angle_rad: give either angle_deg or angle_rad, not both"),
    ("# the rig\n[hexapod]\nbase_radius_m = 1.6\nleg_speed_m_s = 1\n",
     "rig.toml:2: hexapod: missing home_height_m, leg_min_m, leg_max_m"),
    (HEXAPOD.replace("leg_min_m = 1.6", "leg_min_m = 2.4"),
     "rig.toml:6: hexapod.home_height_m: the home pose is outside the stroke: leg 1 length 2.3417 m is not in "
     "[2.4000, 2.8500] m"),
    (HEXAPOD.replace("platform_half_angle_deg = 10", "platform_half_angle_deg = 60"),
     "rig.toml:5: hexapod.platform_half_angle_deg: must be at least 0 and below 60° (π/3 rad), got 60.0"),
    (HEXAPOD + "base_joints_m = [[0, 0, 0]]\n",
     "rig.toml:10: hexapod.base_joints_m: give either the symmetric layout or explicit joints, not both"),
    ("[hexapod]\nbase_joints_m = [[0, 0, 0]]\nplatform_joints_m = []\nhome_height_m = 2\nleg_min_m = 1\n"
     "leg_max_m = 3\nleg_speed_m_s = 1\n",
     "rig.toml:2: hexapod.base_joints_m: expected 6 joints [[x, y, z], ...] in metres, got [[0, 0, 0]]"),
    ("[table]\ncontroller_rate_hz = true\n", "rig.toml:2: table.controller_rate_hz: expected a number, got True"),
    ("[limits]\nheave.velocity_m_s = 0.3\nsurge = { velocity_m_s = 0 }\n",
     "rig.toml:3: limits.surge.velocity_m_s: must be from 0.001 m/s to 5 m/s, got 0.0"),
])
def test_config_errors_word_for_word(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "rig.toml"
    path.write_text(text)
    with pytest.raises(TableModelError) as caught:
        TableModel.from_toml(path)
    assert str(caught.value) == f"{tmp_path}/{message}"


def test_missing_file_and_dict_errors(tmp_path: Path) -> None:
    with pytest.raises(TableModelError) as caught:
        TableModel.from_toml(tmp_path / "nowhere.toml")
    assert str(caught.value) == f"{tmp_path}/nowhere.toml: no such rig configuration file"
    with pytest.raises(TableModelError) as caught:
        TableModel.from_dict({"limits": {"surge": {"acceleration_g": -1}}}, source="session.h5:rig_config")
    assert str(caught.value) == ("session.h5:rig_config: limits.surge.acceleration_g: must be from 0.001 g to 10 g "
                                 "(0.00981 m/s² to 98.1 m/s²), got -1.0")
    with pytest.raises(TableModelError, match=r"^<dict>: limits: expected a table, got 3$"):
        TableModel.from_dict({"limits": 3})


def test_the_plate_s_mass_inertia_and_centre_of_gravity_from_the_rig_toml(tmp_path):
    """``[dynamics]`` gives the rigid plate; values outside a rigid body's physics are errors naming file, line, key."""
    from analysis.table.dynamics import TableDynamics

    path = tmp_path / "rig.toml"
    path.write_text("[dynamics]\nplate_mass_kg = 1200\nplate_inertia_x_kg_m2 = 800\nplate_inertia_y_kg_m2 = 900\n"
                    "plate_inertia_z_kg_m2 = 1600\nplate_cg_x_m = 0.02\nplate_cg_z_m = -0.2\n")
    model = TableModel.from_toml(path)
    assert model.dynamics == TableDynamics(plate_mass=1200.0, plate_inertia_x=800.0, plate_inertia_y=900.0,
                                           plate_inertia_z=1600.0, plate_cg_x=0.02, plate_cg_z=-0.2)
    assert TableModel.from_dict(model.to_dict()) == model
    bad = {
        "plate_inertia_z_kg_m2 = 5000": r"rig.toml:2: dynamics.plate_inertia_z_kg_m2: a rigid body's principal moment "
                                        r"is at most the sum of the other two \(2272.5 kg·m²\), got 5000",
        "plate_cg_z_m = 0.1": r"rig.toml:2: dynamics.plate_cg_z_m: the plate lies below its top surface .* got 0.1",
        "plate_cg_y_m = -2.5": r"rig.toml:2: dynamics.plate_cg_y_m: the centre of gravity is 2.5 m from .* within 2",
        "plate_mass_kg = 0": r"rig.toml:2: dynamics.plate_mass_kg: expected a number from 1 kg to 1e5 kg, got 0",
        "plate_inertia_x_kg_m2 = -1": r"rig.toml:2: dynamics.plate_inertia_x_kg_m2: must be > 0",
    }
    for line, message in bad.items():
        path.write_text(f"[dynamics]\n{line}\n")
        with pytest.raises(TableModelError, match=message):
            TableModel.from_toml(path)


# ----- bounded inputs (issue 25): physical ranges, regular files only, parsers that cannot crash --------------

#: Every number of the rig configuration and its documented range in the key's unit (the module docstring and
#: examples/rig-table4.toml state them beside the keys).
RIG_RANGES: dict[tuple[str, ...], tuple[float, float]] = {
    ("table", "controller_rate_hz"): (10, 5000),
    **{("limits", axis, "displacement_m"): (0.001, 2) for axis in AXES},
    **{("limits", axis, "velocity_m_s"): (0.001, 5) for axis in AXES},
    **{("limits", axis, "acceleration_g"): (0.001, 10) for axis in AXES},
    ("limits", "tilt", "angle_deg"): (0.1, 45), ("limits", "tilt", "rate_deg_s"): (0.01, 90),
    ("limits", "tilt", "acceleration_deg_s2"): (0.01, 360), ("limits", "tilt", "jerk_deg_s3"): (0.01, 3600),
    ("hexapod", "base_radius_m"): (0.05, 20), ("hexapod", "platform_radius_m"): (0.05, 20),
    ("hexapod", "platform_joint_depth_m"): (0, 2), ("hexapod", "home_height_m"): (0.05, 20),
    ("hexapod", "leg_min_m"): (0.05, 20), ("hexapod", "leg_max_m"): (0.05, 20),
    ("hexapod", "leg_speed_m_s"): (0.001, 5), ("hexapod", "base_half_angle_deg"): (0, 60),
    ("dynamics", "bore_m"): (0.005, 1), ("dynamics", "bulk_modulus_pa"): (1e7, 1e10),
    ("dynamics", "line_volume_m3"): (0, 1), ("dynamics", "plate_mass_kg"): (1, 1e5),
    ("dynamics", "piston_mass_kg"): (0.1, 1e4), ("dynamics", "damping_ratio"): (0.001, 0.999),
    ("dynamics", "valve_bandwidth_hz"): (1, 1e4), ("dynamics", "loop_gain_per_s"): (0.01, 1000),
    ("dynamics", "velocity_feedforward"): (0, 1.5),
}
ANY_VALUE = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-(2**63), 2**63 - 1), st.booleans(),
    st.text(max_size=6), st.lists(st.integers(), max_size=2),
    st.sampled_from([1e-300, 1e300, 1e308, 9.2e18, 1e9, 1e-9, 0, -1]),
)


@settings(max_examples=150, deadline=None, derandomize=True, database=None)
@given(key=st.sampled_from(sorted(RIG_RANGES)), value=ANY_VALUE)
def test_any_value_of_a_rig_key_is_refused_at_its_line_or_inside_its_range(
    tmp_path_factory: pytest.TempPathFactory, key: tuple[str, ...], value: object,
) -> None:
    import tomllib

    import tomli_w

    data = tomllib.loads(EXAMPLE.read_text())
    data.setdefault("hexapod", {})
    section = data
    for part in key[:-1]:
        section = section.setdefault(part, {})
    section[key[-1]] = value
    path = tmp_path_factory.mktemp("rig") / "rig.toml"
    text = tomli_w.dumps(data)
    path.write_text(text)
    try:
        TableModel.from_toml(path)
    except TableModelError as exc:
        assert str(exc).startswith(f"{path}:"), str(exc)
        line = int(str(exc).removeprefix(f"{path}:").partition(":")[0])
        assert 1 <= line <= text.count("\n"), str(exc)
        return
    low, high = RIG_RANGES[key]
    assert isinstance(value, int | float) and not isinstance(value, bool) and low <= value <= high, value


def fuzz_rig_bytes(tmp_path: Path, examples: int) -> None:
    """Byte mutations of the example file: a TableModel or a TableModelError naming the file, nothing else."""
    original = EXAMPLE.read_bytes()
    path = tmp_path / "rig.toml"
    tokens = [b"[", b"{", b"=", b"\"", b"1e308", b"-1", b"nan", b"inf", b"1e-300", b"9.2e18", b"[" * 300, b"\xff",
              b"[hexapod]", b"leg_max_m = 1e19", b"controller_rate_hz = 1e9", b"base_joints_m = [[1, 2]]"]

    @settings(max_examples=examples, deadline=None, derandomize=True, database=None)
    @given(st.lists(st.tuples(st.floats(0.0, 1.0, exclude_max=True), st.sampled_from(tokens), st.booleans()),
                    min_size=1, max_size=3))
    def run(edits: list[tuple[float, bytes, bool]]) -> None:
        data = original
        for where, token, replace_line in edits:
            lines = data.splitlines(keepends=True)
            i = int(where * len(lines))
            if replace_line:
                lines[i] = token + b"\n"
                data = b"".join(lines)
            else:
                at = int(where * len(data))
                data = data[:at] + token + data[at:]
        path.write_bytes(data)
        try:
            TableModel.from_toml(path)
        except TableModelError as exc:
            assert str(exc).startswith(f"{path}"), str(exc)

    run()


def test_byte_mutated_rig_files_raise_only_table_model_errors(tmp_path: Path) -> None:
    fuzz_rig_bytes(tmp_path, examples=150)


@pytest.mark.slow
def test_byte_mutated_rig_files_raise_only_table_model_errors_deep(tmp_path: Path) -> None:
    fuzz_rig_bytes(tmp_path, examples=3000)


@pytest.mark.parametrize(("text", "message"), [
    ("[table]\ncontroller_rate_hz = 1e9\n", "rig.toml:2: table.controller_rate_hz: must be from 10 Hz to 5000 Hz, "
     "got 1000000000.0"),
    ("[limits.surge]\nvelocity_m_s = 1e308\n", "rig.toml:2: limits.surge.velocity_m_s: must be from 0.001 m/s to "
     "5 m/s, got 1e+308"),
    (HEXAPOD.replace("leg_max_m = 2.85", "leg_max_m = 9.2e18"),
     "rig.toml:8: hexapod.leg_max_m: must be from 0.05 m to 20 m, got 9.2e+18"),
    ("[dynamics]\ndamping_ratio = 1e-300\n", "rig.toml:2: dynamics.damping_ratio: expected a number from 0.001 "
     "to 0.999 (< 1: an underdamped oil column), got 1e-300"),
    ("x = " + "[" * 5000 + "\n", "rig.toml: TOML syntax error: arrays or tables nested too deeply to parse; "
     "expected at most a few levels"),
])
def test_absurd_rig_values_are_refused_word_for_word(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "rig.toml"
    path.write_text(text)
    with pytest.raises(TableModelError) as caught:
        TableModel.from_toml(path)
    assert str(caught.value) == f"{tmp_path}/{message}"


def test_a_fifo_as_rig_file_is_refused_without_blocking(tmp_path: Path) -> None:
    """Nobody writes to the FIFO: a reader that opened it for reading would wait for a writer forever."""
    import os

    path = tmp_path / "rig.toml"
    os.mkfifo(path)
    with pytest.raises(TableModelError) as caught:
        TableModel.from_toml(path)
    assert str(caught.value) == (f"{path}: is a FIFO (named pipe); expected a rig configuration file "
                                 "(a regular file)")
