"""Safety of every play: the predicted response against closed forms (a constant gain, a pure delay), a drive whose
prediction leaves the table refused with the time, axis, value and limit, the level ramp, the headroom of ``rig
prepare`` and of a sequence file, and the measures (TRAC, response-spectrum error) against closed forms."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from scipy.signal import windows
from typer.testing import CliRunner

from analysis.body import G
from analysis.table.model import AXES, TableModel
from rig.cli import app
from rig.compensation.identify import FrequencyResponse, identification_drive
from rig.compensation.iteration import compensate, error_window, refusal
from rig.compensation.laws import DiagonalLaw
from rig.compensation.measures import measure, trac
from rig.compensation.safety import PredictedLimitError, at_level, check_prediction, predicted_trajectory
from rig.drive import DriveError, DriveRefusedError, parse_headroom, prepare_drive
from rig.drive.file import load_drive, save_drive
from rig.records import load_record
from rig.sequence import SequenceError, load_sequence

TABLE = TableModel()
RECORD = "fema-farfield:NORTHR/MUL009"


def _flat(gain: complex | np.ndarray, band: tuple[float, float] = (0.01, 400.0)) -> FrequencyResponse:
    """A response of ``gain`` on every axis (a constant, or (m,) values on the grid below) over ``band``."""
    f = np.linspace(0.0, 500.0, 5001)
    h = np.broadcast_to(np.asarray(gain, complex).reshape(-1, 1) * np.ones((1, 3)), (len(f), 3)).copy()
    return FrequencyResponse(f=f, h=h, coherence=np.ones((len(f), 3)), band=band)


@pytest.fixture(scope="module")
def random_drive():
    """The band-limited random drive at half of Table IV on every axis, plate level, up to 20 Hz; its corner set to
    0.1 Hz so that a correction may reach all of its content (the band's quarter-octave edges included)."""
    drive = identification_drive(TABLE, 0.0, duration=20.0, level=0.5, band=(1.0, 20.0), seed=2)
    return dataclasses.replace(drive, corner_frequency=0.1)


def test_a_constant_gain_predicts_that_multiple_of_the_drive(random_drive):
    poses, velocities, accelerations = predicted_trajectory(random_drive, _flat(1.5))
    scale = np.abs(random_drive.accelerations[:, :3]).max()
    assert accelerations[:, :3] == pytest.approx(1.5 * random_drive.accelerations[:, :3], abs=1e-3 * scale)
    assert poses[:, :3] == pytest.approx(1.5 * random_drive.poses[:, :3], abs=1e-3 * 0.25)
    assert velocities[:, :3] == pytest.approx(1.5 * random_drive.velocities[:, :3], abs=1e-3 * 0.5)
    assert np.array_equal(poses[:, 3:], random_drive.poses[:, 3:])


def test_a_pure_delay_predicts_the_drive_shifted(random_drive):
    """H = exp(−iωτ), τ = 10 samples: the prediction is the commanded acceleration 10 samples later."""
    f = np.linspace(0.0, 500.0, 5001)
    _, _, accelerations = predicted_trajectory(random_drive, _flat(np.exp(-2j * math.pi * f * 0.010)))
    a = random_drive.accelerations[:, :3]
    assert accelerations[10:, :3] == pytest.approx(a[:-10], abs=2e-3 * np.abs(a).max())


def test_a_drive_whose_prediction_leaves_the_table_is_not_played(random_drive):
    """At half of Table IV on a table that doubles and a half every motion: the prediction is 1.25 × the limits.
    Played at 0 dB at once it is refused (time, axis, value, limit named, nothing played); with a ramp from −12 dB
    the first play is a quarter of it and the correction brings the full-level play within the limits and the
    target."""
    table_gain = 2.5
    played = []

    def play(drive, _index):  # the table that multiplies every motion by 2.5: specific force a − g, plate level
        played.append(drive)
        force = table_gain * drive.accelerations[:, :3]
        force[:, 2] += G
        return force

    violation = check_prediction(random_drive, _flat(table_gain))
    assert violation is not None and violation.where in AXES
    assert abs(violation.value) > violation.limit
    with pytest.raises(PredictedLimitError) as caught:
        compensate(random_drive, DiagonalLaw(_flat(table_gain), gain=1.0), play, iterations=1, levels_db=(0.0,))
    message = str(caught.value)
    assert not played
    assert f"t = {violation.time:.3f} s" in message and violation.where in message and "exceeds the limit" in message
    assert caught.value.fits_at_db == -6.0 and "at -6 dB it fits" in message  # 1.25 × ½ < 1 ≤ 1.25
    result = compensate(random_drive, DiagonalLaw(_flat(table_gain), gain=1.0, regularisation=1e-6), play,
                        iterations=1, levels_db=(-12.0, 0.0))
    assert [it.level_db for it in result.iterations] == [-12.0, 0.0]
    assert played[0].accelerations[:, :3] == pytest.approx(10 ** (-12 / 20) * random_drive.accelerations[:, :3])
    for it in result.iterations:
        assert it.measures.peak_to_limit <= 1.0
    assert result.iterations[-1].rms_error_pct < 1.0
    first = result.iterations[0]  # the exact response: what the play was checked on is what it made
    assert first.predicted_peak_to_limit == pytest.approx(first.measures.peak_to_limit, rel=0.01)
    assert first.to_json()["predicted_peak_to_limit"] == first.predicted_peak_to_limit


def _sine(drive, frequency: float, acceleration: float, axis: str = "surge"):
    """``drive``'s time base carrying only a sine on ``axis`` of ``frequency`` [Hz] and peak ``acceleration``
    [m/s²] under a Tukey envelope (0.5 s ramps), its velocity and acceleration the gradients of its displacement."""
    omega = 2.0 * math.pi * frequency
    envelope = np.zeros(len(drive.t))
    start, end = (round(x * drive.rate) for x in drive.motion)
    envelope[start:end] = windows.tukey(end - start, alpha=2 * 0.5 * drive.rate / (end - start))
    poses = np.zeros_like(drive.poses)
    poses[:, AXES.index(axis)] = acceleration / omega**2 * envelope * np.sin(omega * drive.t)
    velocities = np.gradient(poses, axis=0) * drive.rate
    accelerations = np.gradient(velocities, axis=0) * drive.rate
    return dataclasses.replace(drive, poses=poses, velocities=velocities, accelerations=accelerations,
                               components=(axis,))


def test_a_command_beyond_table_iv_whose_response_stays_inside_is_played(random_drive):
    """A 15 Hz surge target of 0.5 g on a table that halves every motion at 15 Hz: the exact correction commands
    1.0 g (beyond Table IV's 0.6 g, 1.1 mm, 0.12 m/s), its predicted response is 0.5 g — it is played, the plate's
    achieved acceleration stays within Table IV and reaches the target. The same command on a table that passes
    0.7 of it (0.7 g predicted) is refused with the time, axis, predicted value and limit; one whose legs would
    need more than their speed is refused for the legs, whatever the response."""
    target = _sine(random_drive, 15.0, 0.5 * G)
    limit = TABLE.limits.surge.acceleration
    played = []

    def play(drive, _index):  # the table that halves every motion: specific force a − g, plate level
        played.append(drive)
        force = 0.5 * drive.accelerations[:, :3]
        force[:, 2] += G
        return force

    result = compensate(target, DiagonalLaw(_flat(0.5), gain=1.0, regularisation=1e-6), play, iterations=2,
                        levels_db=(0.0,))
    commanded = np.abs(played[-1].accelerations[:, 0]).max()
    assert commanded > 1.6 * limit  # the command asks 1.0 g …
    violation = TABLE.check_trajectory(played[-1].t, played[-1].poses, played[-1].velocities,
                                       played[-1].accelerations)
    assert violation is not None and violation.quantity == "acceleration"  # … which Table IV would have refused
    assert all(it.measures.peak_to_limit <= 1.0 for it in result.iterations)
    assert result.iterations[0].rms_error_pct == pytest.approx(50.0) and result.iterations[-1].rms_error_pct < 5.0
    command = played[-1]
    assert TABLE.check_command(command.t, command.poses, command.velocities, command.accelerations) is None

    too_much = refusal(command, DiagonalLaw(_flat(0.7)))
    predicted = check_prediction(command, _flat(0.7))
    assert predicted is not None and predicted.where == "surge" and predicted.quantity == "acceleration"
    assert limit < abs(predicted.value) <= 0.7 * commanded * 1.01 and predicted.limit == limit  # the first breach
    assert too_much == f"its predicted response leaves the table: {predicted.message()}"
    assert f"at t = {predicted.time:.3f} s surge acceleration" in too_much and "limit ±5.8860 m/s²" in too_much

    fast = _sine(random_drive, 5.0, 36.0, "heave")  # 1.15 m/s of heave: the legs beyond their 0.9 m/s
    assert TABLE.check_command(fast.t, fast.poses).quantity == "speed"
    legs = refusal(fast, DiagonalLaw(_flat(0.1)))  # its predicted response (0.37 g, 0.11 m/s) would fit
    assert check_prediction(fast, _flat(0.1)) is None
    assert legs is not None and legs.startswith("the command leaves the table: at t = ") and "leg" in legs
    assert "speed" in legs


def test_a_drive_file_beyond_table_iv_needs_its_full_level_play_inside(tmp_path, random_drive):
    """A compensated drive whose command asks 1.0 g is read back when its record shows its full-level play with
    the plate within Table IV; without that record it is held to Table IV and refused, naming the breach."""
    command = _sine(random_drive, 15.0, 1.0 * G)
    played = {"best": 1, "iterations": [{"level_db": -6.0, "peak_to_limit": 0.4},
                                        {"level_db": 0.0, "peak_to_limit": 0.85}]}
    back = load_drive(save_drive(tmp_path / "played.h5", command, played), TABLE)
    assert np.array_equal(back.accelerations, command.accelerations)
    beyond = {"best": 1, "iterations": [played["iterations"][0], {"level_db": 0.0, "peak_to_limit": 1.02}]}
    for name, record in (("unplayed.h5", {}), ("beyond.h5", beyond)):
        with pytest.raises(DriveRefusedError, match=r"at t = [0-9.]+ s surge acceleration .* exceeds the limit"):
            load_drive(save_drive(tmp_path / name, command, record), TABLE)


def test_at_level_scales_the_translations_only(random_drive):
    tilted = identification_drive(TABLE, math.radians(4.0), duration=10.0, seed=1)
    quieter = at_level(tilted, -6.0)
    assert quieter.poses[:, :3] == pytest.approx(10 ** (-6 / 20) * tilted.poses[:, :3])
    assert np.array_equal(quieter.poses[:, 3:], tilted.poses[:, 3:])
    with pytest.raises(ValueError, match="dB"):
        at_level(tilted, 3.0)


def test_headroom_leaves_that_margin_on_every_limit():
    motion = load_record(RECORD)
    full = prepare_drive(motion, table=TABLE, ramps=False)
    kept = prepare_drive(motion, table=TABLE, ramps=False, headroom=parse_headroom("10%"))
    assert full.scale_factor < 1.0
    assert kept.scale_factor == pytest.approx(0.9 * full.scale_factor, rel=1e-9)
    assert kept.headroom == 0.1 and kept.to_json()["headroom"] == 0.1
    for axis in AXES:
        for quantity, value in kept.peaks[axis].items():
            assert value <= 0.9 * getattr(TABLE.limits.axis(axis), quantity) * (1 + 1e-9)
    gov = kept.governing
    assert kept.peaks[gov.axis][gov.quantity] == pytest.approx(0.9 * gov.limit)
    assert parse_headroom("0.05") == 0.05
    for bad in ("60%", "-1%", "ten"):
        with pytest.raises(DriveError, match="headroom"):
            parse_headroom(bad)


def test_rig_prepare_headroom_option():
    result = CliRunner().invoke(app, ["prepare", RECORD, "--headroom", "10%", "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    plain = prepare_drive(load_record(RECORD), table=TABLE)
    assert out["headroom"] == 0.1 and out["scale_factor"] == pytest.approx(0.9 * plain.scale_factor)
    bad = CliRunner().invoke(app, ["prepare", RECORD, "--headroom", "70%"])
    assert bad.exit_code == 2 and "headroom" in bad.output


def test_a_sequence_file_sets_the_headroom(tmp_path):
    text = f'name = "h"\nangles_deg = [0]\nrecords = ["{RECORD}"]\n\n[drive]\nheadroom_pct = 10\n\n' \
           '[[bodies]]\ntable5 = 4\nx = 0.0\ny = 0.0\n'
    path = tmp_path / "seq.toml"
    path.write_text(text)
    sequence = load_sequence(path)
    assert sequence.drive.headroom == pytest.approx(0.1)
    drive = sequence.prepare(sequence.plan()[0])
    assert drive.scale_factor == pytest.approx(0.9 * prepare_drive(load_record(RECORD), table=TABLE).scale_factor)
    path.write_text(text.replace("headroom_pct = 10", "headroom_pct = 80"))
    with pytest.raises(SequenceError) as caught:
        load_sequence(path)
    assert "seq.toml:6: drive.headroom_pct" in str(caught.value)


def test_measures_against_closed_forms(random_drive):
    """TRAC of a signal with a scaled copy is 1, with a quadrature one 0; achieved = 1.1 × target gives 10 % RMS,
    peak and response-spectrum error on every period (the oscillator is linear), and a peak / limit of 1.1 × the
    target's."""
    t = np.linspace(0.0, 1.0, 1001)
    assert trac(np.sin(2 * math.pi * 3 * t), 2 * np.sin(2 * math.pi * 3 * t)) == pytest.approx(1.0)
    assert trac(np.sin(2 * math.pi * 3 * t), np.cos(2 * math.pi * 3 * t)) == pytest.approx(0.0, abs=1e-3)
    assert trac(t, 0 * t) is None
    target = random_drive.accelerations[:, :3]
    m = measure(random_drive, target, 1.1 * target, error_window(random_drive), 45.0)
    assert m.rms_error_pct == pytest.approx(10.0, rel=1e-6)
    assert m.psa_error_max_pct == pytest.approx(10.0, rel=1e-6)
    assert m.psa_error_mean_pct == pytest.approx(10.0, rel=1e-6)
    for axis in AXES:
        assert m.axes[axis]["rms_error_pct"] == pytest.approx(10.0, rel=1e-6)
        assert m.axes[axis]["trac"] == pytest.approx(1.0)
    assert 0.5 < m.peak_to_limit < 1.1 * 0.5 * 1.01


def test_headroom_on_the_legs_when_they_bind_first():
    """Legs slower than the default (0.2 m/s): the drive without headroom is refused for a leg's speed; with 10 %
    its motion is scaled until the legs use at most 90 % of their speed (their speed is linear in the scale)."""
    slow = dataclasses.replace(TABLE, geometry=dataclasses.replace(TABLE.geometry, leg_speed=0.2))
    motion = load_record(RECORD)
    with pytest.raises(DriveError, match="speed"):
        prepare_drive(motion, table=slow, ramps=False)
    kept = prepare_drive(motion, table=slow, ramps=False, headroom=0.1)
    speeds = np.abs(slow.leg_velocities(kept.poses, kept.velocities)).max()
    assert 0.89 * 0.2 <= speeds <= 0.9 * 0.2 * (1 + 1e-9)
    assert kept.scale_factor < prepare_drive(motion, table=TABLE, ramps=False, headroom=0.1).scale_factor
