"""The limit detectors' evaluation on the host (rig/orchestrator/limits.py): persistence across batches, warning
and abort levels, one trip per level and run, the channels' instances, the velocity between statuses, the
link's age on a stepped host clock."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.table.limit_detectors import Detector, LimitDetectors
from rig.orchestrator.limits import LINK_AGE_PERIOD_NS, ChannelWatch, LimitWatch, Trip, first_trip


@pytest.mark.parametrize(("past", "carry", "persistence", "expected"), [
    ([False, True, True, False], 0, 2, (2, 0)),
    ([False, True, False, True], 0, 2, (None, 1)),
    ([True, False], 1, 2, (0, 0)),          # the count goes on from the batch before
    ([True, True, True], 5, 10, (None, 8)),
    ([], 3, 4, (None, 3)),
    ([True], 0, 1, (0, 1)),
])
def test_first_trip_counts_consecutive_samples_across_batches(past: list[bool], carry: int, persistence: int,
                                                               expected: tuple[int | None, int]) -> None:
    assert first_trip(np.array(past, dtype=bool), carry, persistence) == expected


def test_a_persistence_of_n_ignores_a_single_spike_and_trips_on_n_in_a_row() -> None:
    watch = ChannelWatch(Detector("accel.x", abort_high=5.0, persistence=3), "accel.0.x")
    t = np.arange(8) * 0.001
    spike = np.array([0, 9, 0, 0, 9, 9, 0, 0], dtype=float)
    assert watch.feed(t, spike) == []
    assert watch.feed(t + 0.008, np.array([9.0])) == []  # 1 in a row (the batch before ended clear)
    trips = watch.feed(t + 0.009, np.array([6.0, 7.0, 0.0]))
    assert trips == [Trip("accel.0.x", "abort_high", 7.0, 5.0, "m/s²", pytest.approx(0.010), "controlled_stop")]


def test_warnings_only_record_and_each_level_trips_once_per_run() -> None:
    watch = ChannelWatch(Detector("accel.x", abort_low=-8.0, warn_low=-4.0, warn_high=4.0, abort_high=8.0,
                                  action="pause"), "accel.1.x")
    t = np.arange(5) * 0.01
    trips = watch.feed(t, np.array([0.0, 5.0, 9.0, -5.0, 9.0]))
    assert [(trip.level, trip.t, trip.action) for trip in trips] == [
        ("warn_high", 0.01, "record"), ("abort_high", 0.02, "pause"), ("warn_low", 0.03, "record")]
    assert watch.feed(t + 1, np.array([9.0, -9.0])) == [Trip("accel.1.x", "abort_low", -9.0, -8.0, "m/s²", 1.01,
                                                             "pause")]
    assert trips[1].text() == "limit accel.1.x: 9 m/s² past abort high 8 m/s²: pause (host)"


def test_each_accelerometer_and_body_is_its_own_instance() -> None:
    watch = LimitWatch(LimitDetectors((Detector("accel.z", abort_high=12.0), Detector("tilt.angle", warn_high=0.3))))
    t = np.array([0.0, 0.001])
    assert watch.accel("0", t, np.array([[0, 0, 9.8], [0, 0, 9.8]])) == []
    [trip] = watch.accel("1", t, np.array([[20.0, 0, 9.8], [0, 0, 13.0]]))  # x has no detector
    assert (trip.channel, trip.value, trip.t) == ("accel.1.z", 13.0, 0.001)
    assert [trip.channel for trip in watch.tilt(2, t, np.array([0.1, 0.4]))] == ["tilt.2.angle"]
    assert watch.tilt(2, t + 1, np.array([0.5])) == []  # tripped already this run


def test_the_velocity_is_the_difference_of_consecutive_statuses() -> None:
    watch = LimitWatch(LimitDetectors((Detector("velocity.heave", abort_high=0.5),
                                       Detector("pose.heave", warn_low=-0.1))))
    pose = np.zeros((2, 6))
    pose[:, 2] = [0.0, 0.008]                       # 0.4 m/s over 20 ms
    assert watch.poses(np.array([0.0, 0.02]), pose) == []
    later = np.zeros((1, 6))
    later[0, 2] = 0.02                              # 0.6 m/s from the last status of the batch before
    [trip] = watch.poses(np.array([0.04]), later)
    assert (trip.channel, trip.value, trip.t) == ("velocity.heave", pytest.approx(0.6), 0.04)
    later[0, 2] = -0.2
    assert [trip.level for trip in watch.poses(np.array([0.06]), later)] == ["warn_low"]


def test_each_leg_s_following_error_is_its_own_instance() -> None:
    watch = LimitWatch(LimitDetectors((Detector("leg.following_error", abort_low=-0.002, abort_high=0.002,
                                                persistence=2),)))
    errors = np.zeros((4, 6))
    errors[1:, 2] = 0.003  # leg 3: three statuses past the level, the second completes the persistence
    errors[2, 5] = -0.004  # leg 6: a single status: ignored
    trips = watch.following_errors(np.array([0.0, 0.02, 0.04, 0.06]), errors)
    assert trips == [Trip("leg.3.following_error", "abort_high", 0.003, 0.002, "m", 0.04, "controlled_stop")]
    assert trips[0].text() == "limit leg.3.following_error: 0.003 m past abort high 0.002 m: controlled_stop (host)"


MS = 1_000_000
"""A millisecond [ns]."""


def test_the_link_s_age_is_sampled_on_the_host_s_clock_whether_statuses_come_or_not() -> None:
    """A stepped host clock: statuses every 20 ms of run and host time, the host's loop looking 3 ms after each;
    one status 45 ms late (the age passes the warning level at one sample only), then silence."""
    assert LINK_AGE_PERIOD_NS == 10 * MS  # samples at the first arrival + 10 ms, + 20 ms, …
    watch = LimitWatch(LimitDetectors((
        Detector("link.age", warn_high=0.055, abort_high=0.1, persistence=2, action="controlled_stop"),)))
    origin = 1_000 * MS  # host monotonic time the run's status of t = 0 arrived
    trips = watch.link([(origin, 0.0)], origin)
    for k in range(1, 5):  # on time: ages of 0 and 10 ms
        trips += watch.link([(origin + k * 20 * MS, k * 0.02)], origin + k * 20 * MS + 3 * MS)
    # the status of run time 0.10 s arrives at 145 ms, not 100 ms: the samples at 130 ms (50 ms old) and 140 ms
    # (60 ms: past the warning level, once) see it missing; the host's loop saw nothing come at 103, 123, 143 ms
    for now in (103, 123, 143):
        trips += watch.link([], origin + now * MS)
    trips += watch.link([(origin + 145 * MS, 0.10), (origin + 146 * MS, 0.12)], origin + 150 * MS)
    assert trips == []  # a single late status: a persistence of 2 ignores it
    # then silence after the status that arrived at 146 ms: the host's own loop finds the age growing
    assert watch.link([], origin + 210 * MS) == []  # 200 ms: 54 ms old; 210 ms: 64 ms, once
    trips = watch.link([], origin + 230 * MS)  # 220 ms: 74 ms, twice in a row
    assert trips == [Trip("link.age", "warn_high", pytest.approx(0.074), 0.055, "s", pytest.approx(0.194), "record")]
    trips = watch.link([], origin + 260 * MS)  # 250 ms: 104 ms; 260 ms: 114 ms
    assert trips == [Trip("link.age", "abort_high", pytest.approx(0.114), 0.1, "s", pytest.approx(0.234),
                          "controlled_stop")]  # the run time: the latest status's (0.12 s) plus its age
    assert trips[0].text() == "limit link.age: 0.114 s past abort high 0.1 s: controlled_stop (host)"
    assert watch.link([(origin + 270 * MS, 0.24)], origin + 400 * MS) == []  # each level trips once per run


def test_a_status_stamped_before_a_sample_already_taken_still_counts_for_the_next() -> None:
    watch = LimitWatch(LimitDetectors((Detector("link.age", warn_high=0.015),)))
    assert watch.link([(0, 0.0)], 15 * MS) == []  # the sample at 10 ms: 10 ms old
    assert watch.link([(14 * MS, 0.014)], 20 * MS) == []  # at 20 ms, 6 ms old (not 20 ms)
    assert watch.link([], 30 * MS) == [Trip("link.age", "warn_high", pytest.approx(0.016), 0.015, "s",
                                            pytest.approx(0.030), "record")]
