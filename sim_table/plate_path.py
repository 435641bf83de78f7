"""The plate's path through a batch of physics steps, compiled: where each step starts on the cubic Hermite curves
through the plate's samples and the generalised force that keeps the plate's joints on them
(:meth:`sim_table.specimens.SpecimenScene.advance_many`).

One numba pass instead of some sixty numpy calls on small arrays a batch, with the numpy version's arithmetic
operation for operation (the same operands in the same order, no fused multiply-add: numba compiles without
fast-math), so its results are the same bits: tests/emulator/test_plate_path.py compares the two.

Units: times [s], poses ``(surge, sway, heave [m], roll, pitch, yaw [rad])`` and their rates [m/s, rad/s], in the
plate joints' order ``order`` (``sim_table.scene.PLATE_QPOS_ORDER``); forces in the model's generalised units.
"""

from __future__ import annotations

import numpy as np

from analysis.compiled_index import njit


@njit(cache=True)
def plate_steps(times: np.ndarray, poses: np.ndarray, rates: np.ndarray, t0: float, pose0: np.ndarray,
                vel0: np.ndarray, clock: float, dt: float, count: int, order: np.ndarray, plate_rate: np.ndarray,
                scale: float, nv: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The physics steps from the scene's ``clock`` [s] through the samples at ``times`` (k,) [s] where the plate
    has ``poses`` and ``rates`` (k, 6), after the sample (``t0``, ``pose0``, ``vel0``) the scene was last given.

    A step starts at ``clock + j·dt`` (summed step by step, at most ``count + 1`` steps) while it ends at least
    half a step before ``times[-1]``; it lies in the first interval whose end is at least half a step on. The plate
    follows, per interval, the Hermite cubic through its end samples (values, and rates × the interval's span),
    evaluated at each step's start and end; its rate over a step is the difference / ``dt``, and the step's force
    on the plate's six joints ``scale`` × (that rate − the step before's; ``plate_rate`` before the first).

    Returns each step's interval (steps,), the plate's joint positions at the first step's start (6,), the forces
    (steps, ``nv``: zero beyond the plate's joints) and the last step's rate (6,) (``plate_rate`` with no step)."""
    k = len(times)
    half = 0.5 * dt
    end = times[k - 1]
    clocks = np.empty(count + 1)
    steps = 0
    c = clock
    for j in range(count + 1):
        if j:
            c = c + dt
        if c + half <= end:
            clocks[steps] = c
            steps += 1
    interval = np.searchsorted(times, clocks[:steps] + half)
    here0 = np.zeros(6)
    force = np.zeros((steps, nv))
    last = plate_rate.copy()
    for j in range(steps):
        i = interval[j]
        start = t0 if i == 0 else times[i - 1]
        span = times[i] - start
        u_here = (clocks[j] - start) / span
        u_there = (clocks[j] + dt - start) / span
        for col in range(6):
            axis = order[col]
            if i == 0:
                p0, v0 = pose0[axis], vel0[axis]
            else:
                p0, v0 = poses[i - 1, axis], rates[i - 1, axis]
            p1 = poses[i, axis]
            m0 = span * v0
            m1 = span * rates[i, axis]
            c3 = 2.0 * (p0 - p1) + m0 + m1
            c2 = 3.0 * (p1 - p0) - 2.0 * m0 - m1
            here = ((c3 * u_here + c2) * u_here + m0) * u_here + p0
            there = ((c3 * u_there + c2) * u_there + m0) * u_there + p0
            rate = (there - here) / dt
            force[j, col] = scale * (rate - last[col])
            last[col] = rate
            if j == 0:
                here0[col] = here
    return interval, here0, force, last


def load() -> None:
    """Compile :func:`plate_steps` (or load it from numba's cache) now, not in the first batch it steps."""
    still = np.zeros((1, 6))
    plate_steps(np.array([1e-3]), still, still, 0.0, still[0], still[0], 0.0, 1e-3, 3, np.arange(6), still[0], 1.0, 6)
