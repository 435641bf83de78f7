"""The fast engines' step grid: ``fast_rocking.step_window`` with a hint gives what it gives without one."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.fast_rocking import SMALL_ANGLE, small_sincos, step_window

N = 2001
AX = np.sin(np.arange(N) * 0.37)
AY = np.cos(np.arange(N) * 0.11)


@settings(max_examples=400, deadline=None)
@given(
    dt=st.sampled_from([0.01, 0.005, 0.02, 0.0010000000000000002, 0.0033333333333333335]),
    n_sub=st.integers(1, 4),
    k=st.integers(0, N - 1),
    frac=st.sampled_from([0.0, 1e-13, 0.25, 0.5, 0.999999999999, 1.0 - 1e-15, 0.7310585786300049]),
    hint_offset=st.integers(-3, 3),
)
def test_the_hint_never_changes_the_step(dt: float, n_sub: int, k: int, frac: float, hint_offset: int) -> None:
    """Times on and around the samples (rounded grids included): every hint near the right interval, and none,
    give the same window bit for bit — the hint only spares the division."""
    t = (k + frac) * dt
    t_rec = (N - 1) * dt
    h = dt / n_sub
    bare = step_window(AX, AY, dt, h, n_sub, t, t_rec, t_rec + 1.0, -1)
    hinted = step_window(AX, AY, dt, h, n_sub, t, t_rec, t_rec + 1.0, max(bare[7] + hint_offset, -1))
    assert hinted == bare
    if bare[7] >= 0:  # the interval holds t (within the grid's 1e-12 dt) and the step has a length inside it
        assert bare[0] <= t + 1e-12 * dt < bare[2]
        assert t < bare[1] <= bare[2]


@settings(deadline=None)
@given(d=st.floats(-0.3, 0.3))
def test_small_sincos_is_the_library_to_rounding(d: float) -> None:
    """The short series agree with the library to 2 ulp of 1 wherever they are used (and are it beyond)."""
    sn, cs = small_sincos(d)
    assert abs(sn - np.sin(d)) <= 2.3e-16 * max(abs(d), 1e-300) + 1e-300
    assert abs(cs - np.cos(d)) <= 2.3e-16
    if abs(d) > SMALL_ANGLE:
        assert (sn, cs) == (np.sin(d), np.cos(d))
