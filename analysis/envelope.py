"""Block bounds of a record, so that a resting block's scan skips the stretches where it cannot leave rest.

A resting block leaves rest where one of its margins (Eq. 1's uplift margins, the general model's slide and
lift-off margins) turns positive. Every margin is linear in the input: m = c_x a_x + c_y (g + a_y) for the
plate-frame gravity of ``analysis.equations.plate_gravity``. Over a block of ``BLOCK`` samples, the largest
and smallest a_x and a_y bound it from above: where that bound is below zero by more than rounding can make
up (``SLACK``), no sample of the block is an exit, and since the input is linear between samples, neither is
any time between them. The scans (``fast_rocking._next_uplift``, ``fast_general._next_exit``) jump such
blocks and read every sample of the others exactly as before, so they find the same exits, bit for bit.
"""

from __future__ import annotations

import numpy as np

from analysis.body import G
from analysis.compiled_index import njit

BLOCK = 32
"""Samples per block."""
SLACK = 1e-12
"""A block is jumped only if its bound is below −SLACK·(g + its largest |a|): rounding of a margin is
below 1e-15 of that."""


def block_bounds(ax: np.ndarray, ay: np.ndarray) -> np.ndarray:
    """(blocks, 4): per block of ``BLOCK`` samples of ``ax``/``ay`` [m/s²] (samples kB … kB + BLOCK − 1, the
    last block short), the largest and smallest a_x, the largest and smallest a_y [m/s²]."""
    n = ax.shape[0]
    nb = -(-n // BLOCK)
    pad = nb * BLOCK - n
    out = np.empty((nb, 4))
    for col, a in ((0, ax), (2, ay)):
        blocks = np.pad(np.asarray(a, dtype=float), (0, pad), mode="edge").reshape(nb, BLOCK)
        out[:, col] = blocks.max(axis=1)
        out[:, col + 1] = blocks.min(axis=1)
    return out


@njit(cache=True, inline="always")
def margin_bound(u: float, w: float, cb: float, sb: float, bx_max: float, bx_min: float, by_max: float,
                 by_min: float) -> float:
    """Upper bound over a block of the margin u·g_x + w·g_z [m/s²] (g_x = −a_x cos β + (g + a_y) sin β,
    g_z = a_x sin β + (g + a_y) cos β; ``cb``, ``sb`` = cos β, sin β) from the block's extremes of a_x, a_y."""
    cx = -u * cb + w * sb
    cy = u * sb + w * cb
    return cx * (bx_max if cx > 0.0 else bx_min) + cy * (by_max if cy > 0.0 else by_min) + cy * G


@njit(cache=True, inline="always")
def block_slack(bx_max: float, bx_min: float, by_max: float, by_min: float) -> float:
    """How far below zero a block's bound must be to jump it [m/s²] (``SLACK``)."""
    return -SLACK * (G + max(abs(bx_max), abs(bx_min)) + max(abs(by_max), abs(by_min)))
