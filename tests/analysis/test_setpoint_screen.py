"""The setpoint check's compiled screen (``analysis.table.setpoint_screen``): it clears only chunks the numpy check
(``analysis.table.setpoints``) passes, and clears an ordinary drive's, so the controller may skip the check for
those."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from analysis.table import setpoint_screen
from analysis.table.model import TableModel
from analysis.table.setpoint_screen import SetpointScreen
from analysis.table.setpoints import POSITION_ALLOWANCE, RATE_ALLOWANCE, check_setpoints

TABLE = TableModel()


@pytest.fixture(scope="module")
def screen() -> SetpointScreen:
    """The default table's screen, made (its kernel compiled or loaded) by the first test that needs it, not
    at collection, which every xdist worker does for every module."""
    return SetpointScreen(TABLE)


SPACING = 1e-3  # s
SHORT_STROKE = dataclasses.replace(TABLE, geometry=dataclasses.replace(TABLE.geometry, leg_min=2.1, leg_max=2.35))
"""A table whose legs' stroke [m] the envelope reaches (the default one's it does not)."""


def ramp(n: int = 8, speed: float = 0.1) -> np.ndarray:
    """``n`` samples of a surge ramp at ``speed`` [m/s] with the plate tilted 3° (pitch)."""
    samples = np.zeros((n, 6))
    samples[:, 0] = speed * SPACING * np.arange(n)
    samples[:, 4] = math.radians(3.0)
    return samples


def test_the_compiled_pass_is_run_when_the_screen_is_made(monkeypatch: pytest.MonkeyPatch) -> None:
    """The emulator's controller makes its screen at start, so a cold numba cache is filled then: compiled at a
    stream's first chunk instead, the emulator sent no status for seconds and the host took the link for lost
    ("no status for 1.2 s", a first ``rig run --emulate`` after the sources changed)."""
    calls: list[tuple[object, ...]] = []
    monkeypatch.setattr(setpoint_screen, "_clears", lambda *args: calls.append(args) or True)
    SetpointScreen(TABLE)
    assert len(calls) == 1


def test_an_ordinary_chunk_is_cleared_with_its_neighbours(screen: SetpointScreen) -> None:
    samples = ramp()
    previous = (samples[0] - (samples[1] - samples[0]), SPACING)
    following = (samples[-1] + (samples[1] - samples[0]), SPACING)
    assert check_setpoints(TABLE, samples, SPACING, previous, following) is None
    assert screen.clears(samples, SPACING, previous, following)


@pytest.mark.parametrize("column, value", [(2, math.nan), (0, math.inf), (2, 0.3), (4, 0.5)])
def test_a_sample_the_check_refuses_is_not_cleared(column: int, value: float, screen: SetpointScreen) -> None:
    samples = ramp()
    samples[3, column] = value
    assert check_setpoints(TABLE, samples, SPACING) is not None
    assert not screen.clears(samples, SPACING)


def test_a_step_too_fast_from_either_neighbour_is_not_cleared(screen: SetpointScreen) -> None:
    samples = ramp()
    jump = samples[0].copy()
    jump[0] -= 0.01  # 10 mm in 1 ms: 10 m/s
    problem = check_setpoints(TABLE, samples, SPACING, previous=(jump, SPACING))
    assert problem is not None and problem.kind == "rate"
    assert not screen.clears(samples, SPACING, previous=(jump, SPACING))
    assert screen.clears(samples, SPACING, previous=(jump, 1.0))  # 10 mm in 1 s
    assert not screen.clears(samples, SPACING, following=(samples[-1] + (samples[0] - jump), SPACING))
    assert screen.clears(samples, SPACING, previous=(jump, 0.0))  # over no time: not a step, as the check


def test_a_chunk_at_a_limit_is_left_to_the_check(screen: SetpointScreen) -> None:
    samples = ramp()
    samples[:, 2] = TABLE.limits.heave.displacement + POSITION_ALLOWANCE  # exactly on the allowance: may be played
    assert check_setpoints(TABLE, samples, SPACING) is None
    assert not screen.clears(samples, SPACING)


@pytest.mark.parametrize("table, reach", [(TABLE, 1.02), (SHORT_STROKE, 0.6)], ids=["table", "short stroke"])
def test_what_the_screen_clears_the_check_passes_near_every_limit(table: TableModel, reach: float) -> None:
    """Random chunks around the limits (seed 41), starting up to ``reach`` × the envelope: none cleared that the
    check refuses, and most it passes cleared."""
    rng = np.random.default_rng(41)
    screen = SetpointScreen(table)
    lim, g = table.limits, table.geometry
    envelope = np.array([lim.surge.displacement, lim.lateral.displacement, lim.heave.displacement, lim.tilt.angle,
                         lim.tilt.angle, 0.1])
    cleared = passed = 0
    for _ in range(3000):
        start = rng.uniform(-reach, reach, 6) * envelope
        # each coordinate's speed up to a little beyond what the legs and the tilt rate allow
        speed = rng.uniform(-1.1, 1.1, 6) * np.array([g.leg_speed] * 3 + [lim.tilt.rate] * 2 + [0.05])
        samples = start + SPACING * np.arange(8)[:, None] * speed
        previous = (samples[0] - SPACING * speed * rng.uniform(0.0, 1.1 + RATE_ALLOWANCE), SPACING)
        ok = check_setpoints(table, samples, SPACING, previous) is None
        clear = screen.clears(samples, SPACING, previous)
        assert ok or not clear, samples
        passed += ok
        cleared += clear
    assert passed > 100 and cleared >= 0.9 * passed
