"""``sim_table.plate_path.plate_steps`` gives the same bits as the numpy steps it replaced in
``SpecimenScene.advance_many`` (kept here as the reference), over random batches: sizes, sample spacings off the
physics step, a scene clock inside the first interval, plate rates before the batch."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim_table.plate_path import plate_steps
from sim_table.scene import PLATE_ARMATURE, PLATE_QPOS_ORDER
from sim_table.specimens import _evaluate, _hermite

DT = 1e-3
NV = 48


def numpy_steps(times: np.ndarray, poses: np.ndarray, rates: np.ndarray, t0: float, pose0: np.ndarray,
                vel0: np.ndarray, clock: float, plate_rate: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """advance_many's numpy steps before sim_table.plate_path (main at ac2ad24)."""
    order = np.array(PLATE_QPOS_ORDER)
    dt = DT
    starts = np.concatenate([[t0], times[:-1]])
    spans = (times - starts)[:, None]
    paths = _hermite(np.vstack([pose0[None, order], poses[:-1, order]]),
                     spans * np.vstack([vel0[None, order], rates[:-1, order]]),
                     poses[:, order], spans * rates[:, order])
    count = max(0, math.ceil((times[-1] - clock) / dt) + 2)
    clocks = np.cumsum(np.concatenate([[clock], np.full(count, dt)]))
    clocks = clocks[clocks + 0.5 * dt <= times[-1]]
    interval = np.searchsorted(times, clocks + 0.5 * dt)
    steps = [c[interval] for c in paths]
    start, span = starts[interval], spans[interval, 0]
    here_array = _evaluate(steps, ((clocks - start) / span)[:, None])
    there_array = _evaluate(steps, ((clocks + dt - start) / span)[:, None])
    step_rates = (there_array - here_array) / dt
    previous_rates = np.vstack([plate_rate[None, :], step_rates[:-1]])
    force = np.zeros((len(interval), NV))
    force[:, :6] = (PLATE_ARMATURE / dt) * (step_rates - previous_rates)
    return interval, here_array[0], force, step_rates[-1]


@pytest.mark.parametrize("seed", range(40))
def test_the_compiled_steps_are_the_numpy_steps_bit_for_bit(seed: int) -> None:
    rng = np.random.default_rng(seed)
    k = int(rng.integers(1, 80))
    spacing = DT * rng.choice([1.0, 0.5, 2.0, 1.37])
    t0 = float(rng.uniform(0.0, 30.0))
    clock = t0 + float(rng.uniform(-0.5, 0.5)) * DT  # the scene's clock: within half a step of the last sample
    times = t0 + spacing * np.arange(1, k + 1) + rng.uniform(-1e-6, 1e-6, k) * (seed % 2)
    poses, rates = rng.normal(0.0, 0.05, (k, 6)), rng.normal(0.0, 0.3, (k, 6))
    pose0, vel0, plate_rate = rng.normal(0.0, 0.05, 6), rng.normal(0.0, 0.3, 6), rng.normal(0.0, 0.3, 6)
    expected = numpy_steps(times, poses, rates, t0, pose0, vel0, clock, plate_rate)
    count = max(0, math.ceil((times[-1] - clock) / DT) + 2)
    got = plate_steps(times, poses, rates, t0, pose0, vel0, clock, DT, count, np.array(PLATE_QPOS_ORDER),
                      plate_rate, PLATE_ARMATURE / DT, NV)
    assert len(expected[0]) > 0 or k * spacing < DT
    for name, a, b in zip(("interval", "first pose", "force", "last rate"), got, expected, strict=True):
        assert a.shape == b.shape, name
        assert a.tobytes() == b.tobytes(), name
