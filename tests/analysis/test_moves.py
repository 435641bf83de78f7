"""The quintic move shared by the drive's tilt ramps, the emulator and the CANopen master (analysis.table.moves)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.table.model import TableModel
from analysis.table.moves import ACCELERATION_PEAK, JERK_PEAK, RATE_PEAK, Move, axis_limits, quintic, shortest_duration


def test_quintic_peaks_match_the_closed_forms() -> None:
    """Rate, acceleration and jerk of s(τ) sampled finely against 15/8, 10/√3 and 60 (Δ = T = 1)."""
    tau = np.linspace(0.0, 1.0, 2_001)  # coarse enough that three differences keep no round-off noise
    s = quintic(tau)
    rate = np.gradient(s, tau)
    accel = np.gradient(rate, tau)
    jerk = np.gradient(accel, tau)
    assert (s[0], s[-1]) == (0.0, 1.0)
    assert rate.max() == pytest.approx(RATE_PEAK, rel=1e-6)
    assert np.abs(accel).max() == pytest.approx(ACCELERATION_PEAK, rel=1e-4)
    exact_jerk = JERK_PEAK * (1.0 - 6.0 * tau + 6.0 * tau**2)  # the third derivative: |.| peaks at 60 at the ends
    np.testing.assert_allclose(jerk[3:-3], exact_jerk[3:-3], atol=1e-3 * JERK_PEAK)
    assert np.abs(exact_jerk).max() == JERK_PEAK
    assert abs(rate[0]) < 1e-5 and abs(accel[2]) < 0.2  # at rest, no acceleration at the start (one-sided ends)


def test_shortest_move_touches_one_limit_and_breaks_none() -> None:
    table = TableModel()
    start = np.zeros(6)
    end = np.array([0.2, -0.1, 0.05, 0.0, math.radians(7), 0.0])
    move = Move.shortest(0, start, end, table)
    t = np.linspace(0, move.duration_ns, 20_001)
    poses = np.array([move.at(int(k)) for k in t])
    seconds = t * 1e-9
    rate = np.gradient(poses, seconds, axis=0)
    accel = np.gradient(rate, seconds, axis=0)
    velocity_limit, acceleration_limit, _ = axis_limits(table)
    use = np.maximum(np.abs(rate).max(axis=0) / velocity_limit, np.abs(accel).max(axis=0) / acceleration_limit)
    assert use.max() <= 1.0 + 1e-3
    assert use.max() >= 0.99  # as short as the limits allow: one of them is reached
    np.testing.assert_allclose(move.at(move.end_ns), end)
    np.testing.assert_allclose(move.at(-1), start)
    assert move.done(move.end_ns) and not move.done(move.end_ns - 1)


def test_no_change_takes_no_time() -> None:
    assert shortest_duration(np.zeros(6), *axis_limits(TableModel())) == 0.0
    move = Move.shortest(5, np.zeros(6), np.zeros(6), TableModel())
    assert move.duration_ns == 0 and move.done(5)
    np.testing.assert_array_equal(move.at(5), np.zeros(6))
