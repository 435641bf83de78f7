"""The rest scans' block skip (analysis/envelope.py) finds the same exits as reading every sample."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.body import G
from analysis.envelope import BLOCK, block_bounds
from analysis.fast_general import _next_exit
from analysis.fast_rocking import _next_uplift


def no_skip(n: int) -> np.ndarray:
    """Block bounds that never allow a jump (every margin may be positive)."""
    out = np.empty((-(-n // BLOCK), 4))
    out[:, 0::2], out[:, 1::2] = 1e300, -1e300
    return out


def test_block_bounds_hold_each_block_s_extremes() -> None:
    rng = np.random.default_rng(3)
    ax, ay = rng.normal(size=100), rng.normal(size=100)
    env = block_bounds(ax, ay)
    assert env.shape == (4, 4)  # 100 samples: three full blocks of 32 and one of 4
    for k in range(4):
        sl = slice(k * BLOCK, (k + 1) * BLOCK)
        assert tuple(env[k]) == (ax[sl].max(), ax[sl].min(), ay[sl].max(), ay[sl].min())


@pytest.mark.parametrize("seed", range(6))
def test_scans_find_the_same_exits_as_without_the_skip(seed: int) -> None:
    """Quiet stretches with bursts (so blocks are jumped and exits fall just after them), from every start."""
    rng = np.random.default_rng(seed)
    n = 2000
    ax = rng.normal(scale=0.02, size=n) * G
    for c in rng.integers(0, n - 40, size=6):
        ax[c:c + 20] += rng.normal(scale=0.4, size=20) * G
    ay = rng.normal(scale=0.1, size=n) * G if seed % 2 else np.zeros(n)
    ax[-1] = ay[-1] = 0.0
    dt = 0.01
    env, none = block_bounds(ax, ay), no_skip(n)
    beta = math.radians(rng.uniform(0.0, 8.0))
    cb, sb = math.cos(beta), math.sin(beta)
    a_p, a_m = 0.2, 0.25
    for t in rng.uniform(0.0, (n - 1) * dt, size=40):
        assert _next_uplift(ax, ay, env, dt, t, cb, sb, math.tan(a_p), math.tan(a_m)) == \
            _next_uplift(ax, ay, none, dt, t, cb, sb, math.tan(a_p), math.tan(a_m))
        for mu in (0.1, 0.3, 1.0):
            assert _next_exit(ax, ay, env, dt, t, cb, sb, a_p, a_m, mu, bool(seed % 2)) == \
                _next_exit(ax, ay, none, dt, t, cb, sb, a_p, a_m, mu, bool(seed % 2))
