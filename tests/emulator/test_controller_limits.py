"""The controller's own limit levels without sockets: the SET_LIMIT parameters a level travels in, the levels'
evaluation on every tick's accelerometer samples and on every status's pose, velocity and following errors
(persistence, the earliest trip), and the controller core's command and stop (``docs/limits.md``, On the controller)."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.table.controller_limits import CLEAR_CODE, ControllerLevel, ControllerTrip, controller_levels
from analysis.table.limit_detectors import Detector, LimitDetectors
from analysis.table.model import TableModel
from sim_table.controller import Command, ControllerCore, Result, State, StateChange
from sim_table.limit_levels import LimitLevels

MS = 1_000_000
LEVEL = ControllerLevel("accel.x", "abort_high", 4.0, 2, "controlled_stop")


def forces(x: list[float], sensors: int = 1) -> np.ndarray:
    """Samples (k, sensors, 3) whose x is ``x`` on sensor ``sensors - 1`` (0 on the others), z at rest."""
    out = np.zeros((len(x), sensors, 3))
    out[:, :, 2] = 9.81
    out[:, -1, 0] = x
    return out


@pytest.mark.parametrize("level", [
    LEVEL,
    ControllerLevel("accel.z", "abort_low", -19.62, 10_000, "emergency_stop"),
    ControllerLevel("accel.y", "abort_high", 0.123456789, 1, "controlled_stop"),
    ControllerLevel("pose.yaw", "abort_low", -0.5, 7, "emergency_stop"),
    ControllerLevel("velocity.heave", "abort_high", 0.25, 3, "controlled_stop"),
    ControllerLevel("leg.following_error", "abort_high", 0.005, 10_000, "emergency_stop"),
])
def test_a_level_round_trips_through_the_two_command_parameters_in_float32(level: ControllerLevel) -> None:
    code, threshold = (float(np.float32(p)) for p in level.params())  # MAVLink's COMMAND_LONG params are float32
    assert code == level.code()  # exact: the code stays below 2**24
    decoded = ControllerLevel.decode((code, threshold))
    assert decoded.threshold == pytest.approx(level.threshold, rel=1e-7)
    assert (decoded.channel, decoded.side, decoded.persistence, decoded.action) == (
        level.channel, level.side, level.persistence, level.action)


@pytest.mark.parametrize(("params", "problem"), [
    ((0.5, 1.0), "whole number"),
    ((float(CLEAR_CODE), 1.0), "above 0"),
    ((float(ControllerLevel("accel.x", "abort_high", 1.0, 1, "controlled_stop").code() + 64 * 16_384), 1.0),
     "channel 17"),
    ((float(ControllerLevel("pose.heave", "abort_high", 1.0, 1, "controlled_stop").code()), 3.0),
     "not a finite level"),
    ((float(LEVEL.code() - 2), 1.0), "persistence 0"),
    ((float(LEVEL.code()), float("nan")), "not a finite level"),
    ((float(LEVEL.code()), 1e4), "not a finite level"),
])
def test_parameters_that_pack_no_level_are_refused_saying_what(params: tuple[float, float], problem: str) -> None:
    with pytest.raises(ValueError, match=problem):
        ControllerLevel.decode(params)


def test_only_the_abort_levels_that_stop_the_table_on_controller_channels_are_downloaded() -> None:
    detectors = LimitDetectors((
        Detector("accel.x", abort_low=-5.0, warn_low=-1.0, warn_high=1.0, abort_high=5.0, persistence=3),
        Detector("accel.y", abort_high=5.0, action="pause"),
        Detector("accel.z", abort_high=30.0, action="emergency_stop"),
        Detector("pose.heave", abort_high=0.1),
        Detector("velocity.roll", warn_high=0.1, abort_low=-0.2, action="emergency_stop"),
        Detector("leg.following_error", abort_high=0.005, persistence=2),
        Detector("tilt.angle", abort_high=0.3),  # the bodies' tilt sensors: not the controller's
    ))
    assert controller_levels(detectors) == (
        ControllerLevel("accel.x", "abort_low", -5.0, 3, "controlled_stop"),
        ControllerLevel("accel.x", "abort_high", 5.0, 3, "controlled_stop"),
        ControllerLevel("accel.z", "abort_high", 30.0, 1, "emergency_stop"),
        ControllerLevel("pose.heave", "abort_high", 0.1, 1, "controlled_stop"),
        ControllerLevel("velocity.roll", "abort_low", -0.2, 1, "emergency_stop"),
        ControllerLevel("leg.following_error", "abort_high", 0.005, 2, "controlled_stop"))


def test_a_single_spike_does_not_trip_a_persistence_of_two_and_the_second_sample_in_a_row_does() -> None:
    levels = LimitLevels()
    levels.add(LEVEL)
    times = np.arange(6) * MS
    assert levels.accel(times, forces([0.0, 5.0, 0.0, 5.0, 0.0, 0.0])) is None  # spikes, one sample each
    # the count carries across batches: one past at the end of a batch, the next batch's first completes it
    assert levels.accel(times + 6 * MS, forces([0.0, 0.0, 0.0, 0.0, 0.0, 4.5])) is None
    trip = levels.accel(times + 12 * MS, forces([6.0, 7.0, 0.0, 0.0, 0.0, 0.0]))
    assert trip == ControllerTrip(12 * MS, 0, 6.0, LEVEL)
    assert levels.accel(times + 18 * MS, forces([9.0] * 6)) is None  # one trip a stream


def test_the_earliest_trip_among_sensors_and_levels_is_the_one_reported() -> None:
    levels = LimitLevels()
    levels.add(LEVEL)
    levels.add(ControllerLevel("accel.z", "abort_low", 5.0, 1, "emergency_stop"))
    samples = forces([0.0, 0.0, 5.0, 5.0, 0.0], sensors=2)
    samples[3:, 0, 2] = 4.0  # sensor 0's z below 5 m/s² from sample 3, sensor 1's x past 4 from sample 2
    trip = levels.accel(np.arange(5) * MS, samples)
    assert trip is not None and (trip.t_ns, trip.sensor, trip.level.channel) == (3 * MS, 0, "accel.z")
    levels.restart()  # a new stream: counts from zero, may trip again
    assert levels.accel(np.arange(5) * MS, samples) == trip


def test_status_levels_count_statuses_and_name_the_leg_that_tripped() -> None:
    level = ControllerLevel("leg.following_error", "abort_low", -0.005, 2, "controlled_stop")
    levels = LimitLevels()
    levels.add(level)
    times = np.array([20, 40, 60]) * MS
    errors = np.zeros((3, 6))
    errors[2, 2] = -0.006  # leg 3: the last status past the level
    assert levels.batch(times, forces([0.0] * 3), times, np.zeros((3, 6)), errors) is None
    errors[:, 2] = [-0.007, 0.0, 0.0]  # the next batch's first status completes the persistence
    errors[1:, 4] = -0.01  # leg 5: later
    trip = levels.batch(times + 60 * MS, forces([0.0] * 3), times + 60 * MS, np.zeros((3, 6)), errors)
    assert trip == ControllerTrip(80 * MS, 3, -0.007, level)
    assert trip.instance() == "leg.3.following_error"


def test_the_velocity_is_between_consecutive_statuses_as_on_the_host() -> None:
    level = ControllerLevel("velocity.heave", "abort_high", 0.2, 1, "emergency_stop")
    pose_level = ControllerLevel("pose.heave", "abort_high", 0.5, 1, "controlled_stop")
    levels = LimitLevels()
    levels.add(level)
    levels.add(pose_level)
    times = np.array([20, 40]) * MS
    pose = np.zeros((2, 6))
    pose[:, 2] = [0.0, 0.003]  # 0.15 m/s
    assert levels.batch(times, forces([0.0] * 2), times, pose, np.zeros((2, 6))) is None
    pose[:, 2] = [0.0095, 0.012]  # 0.325 m/s from the previous batch's last status
    trip = levels.batch(times + 40 * MS, forces([0.0] * 2), times + 40 * MS, pose, np.zeros((2, 6)))
    assert trip is not None and (trip.t_ns, trip.sensor, trip.level) == (60 * MS, 0, level)
    assert trip.value == pytest.approx(0.325)
    assert trip.instance() == "velocity.heave"
    accel_trip = ControllerTrip(1, 2, 6.0, LEVEL)
    assert accel_trip.instance({2: "A2"}) == "accel.A2.x"


def streaming_with(level: ControllerLevel) -> ControllerCore:
    core = ControllerCore(TableModel())
    assert core.command(Command.ARM, (), True, 0) is Result.ACCEPTED
    assert core.command(Command.SET_LIMIT, level.params(), False, 0) is Result.DENIED  # moves the table: signed
    assert core.command(Command.SET_LIMIT, (0.5, 1.0), True, 0) is Result.FAILED
    assert core.command(Command.SET_LIMIT, level.params(), True, 0) is Result.ACCEPTED
    assert core.command(Command.START_STREAM, (0.0,), True, 0) is Result.ACCEPTED
    assert core.command(Command.SET_LIMIT, (float(CLEAR_CODE), 0.0), True, 0) is Result.REJECTED  # fixed now
    assert core.limit_levels.levels == [level]
    core.take_events()
    return core


def test_a_trip_stops_the_stream_with_the_stop_ramp_at_the_tick_given_and_is_reported() -> None:
    core = streaming_with(LEVEL)
    trip = ControllerTrip(7 * MS, 0, 6.0, LEVEL)
    assert core.limit_trip(trip, 9 * MS)
    assert core.take_events() == [trip, StateChange(9 * MS, State.STREAMING, State.STOPPING)]
    assert core.limit_levels.levels == []  # the stream ended: its levels with it
    assert not core.limit_trip(trip, 10 * MS)  # no stream any more: nothing to act on
    assert core.counters.limit_trips == 1


def test_an_emergency_stop_level_brakes_the_table() -> None:
    level = ControllerLevel("accel.x", "abort_high", 4.0, 1, "emergency_stop")
    core = streaming_with(level)
    assert core.limit_trip(ControllerTrip(7 * MS, 0, 6.0, level), 8 * MS)
    assert core.state is State.EMERGENCY_STOPPED
