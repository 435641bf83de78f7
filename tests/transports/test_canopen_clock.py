"""The CANopen master's clocks (``drivers/canopen/clock.py``): the wall clock a real bus runs on, and the stepped
clock that runs emulated drives in lockstep with the master."""

from __future__ import annotations

import pytest

from drivers.canopen.clock import Clock, SteppedClock, WallClock


def test_a_stepped_clock_settles_the_drives_before_it_jumps_to_the_deadline() -> None:
    seen: list[int] = []
    clock = SteppedClock(lambda: seen.append(clock.now_ns()), start_ns=5_000)
    assert clock.sleep_until(12_000) == 0 and clock.now_ns() == 12_000
    assert seen == [5_000]  # the drives settled at the time before the step
    assert clock.sleep_until(20_000) == 0 and seen == [5_000, 12_000]


def test_a_stepped_clock_never_goes_back_and_reports_a_deadline_it_passed() -> None:
    clock = SteppedClock(start_ns=0)
    clock.advance_to(30_000)
    clock.advance_to(10_000)
    assert clock.now_ns() == 30_000
    assert clock.sleep_until(25_000) == 5_000 and clock.now_ns() == 30_000


def test_a_stepped_clock_refuses_a_negative_start() -> None:
    with pytest.raises(ValueError, match="start_ns must be >= 0"):
        SteppedClock(start_ns=-1)


def test_the_wall_clock_is_monotonic_and_reports_how_late_a_past_deadline_is() -> None:
    clock: Clock = WallClock()
    before = clock.now_ns()
    assert clock.sleep_until(before - 1_000_000) >= 1_000_000
    assert clock.now_ns() >= before
