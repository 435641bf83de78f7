"""The compiled batch: many scenes (body × record × sign × angle) on all cores.

Records are packed into one flat array (each with its trailing zero sample, each sign its own
copy) and the scenes run in a seeded shuffled order so that costly and cheap scenes spread evenly
over the threads. One kernel per model (the general one in :mod:`analysis.batch_general`), so a rocking study
never compiles the general model.
"""

from __future__ import annotations

import numpy as np
from numba import prange

from analysis.compiled_index import njit
from analysis.envelope import BLOCK
from analysis.fast_rocking import simulate_rocking


@njit(cache=True, inline="always")
def fall_angles(static: bool, alpha_p: float, alpha_m: float, beta: float) -> tuple[float, float]:
    """|θ| that counts as overturned towards +x / −x (see ``simulate.fall_angles``)."""
    if static:
        return alpha_p - beta, alpha_m + beta
    return 0.5 * np.pi, 0.5 * np.pi


@njit(cache=True, parallel=True)
def run_rocking(
    ax: np.ndarray, ay: np.ndarray, offsets: np.ndarray, lengths: np.ndarray, env: np.ndarray,
    env_offsets: np.ndarray, dts: np.ndarray,
    scene_series: np.ndarray, scene_body: np.ndarray, scene_beta: np.ndarray, order: np.ndarray,
    alpha_p: np.ndarray, k_p: np.ndarray, alpha_m: np.ndarray, k_m: np.ndarray, n_sub: np.ndarray,
    e_p: np.ndarray, e_m: np.ndarray, t_after: float, static: bool, out_f: np.ndarray, out_i: np.ndarray,
) -> None:
    """Rocking model for every scene. ``env``: every series' ``envelope.block_bounds`` stacked, series q's
    from row ``env_offsets[q]``. Per body: slenderness, k and impact ratio on the +x and −x corners
    (``simulate_rocking``); ``n_sub[series, body]``; outputs per scene:
    ``out_f[:, 0:2]`` = t_overturn, theta_max; ``out_i[:, 0:5]`` = direction, impacts, status,
    steps, prescreened."""
    for idx in prange(order.shape[0]):
        sc = order[idx]
        q, j, beta = scene_series[sc], scene_body[sc], scene_beta[sc]
        a, c = offsets[q], env_offsets[q]
        n_env = (lengths[q] + BLOCK - 1) // BLOCK
        fp, fm = fall_angles(static, alpha_p[j], alpha_m[j], beta)
        res = simulate_rocking(ax[a:a + lengths[q]], ay[a:a + lengths[q]], env[c:c + n_env], dts[q], alpha_p[j],
                               k_p[j], alpha_m[j], k_m[j], beta, e_p[j], e_m[j], n_sub[q, j], t_after, fp, fm, 0.0, 0.0)
        out_f[sc, 0], out_f[sc, 1] = res[1], res[2]
        out_i[sc, 0], out_i[sc, 1], out_i[sc, 2], out_i[sc, 3], out_i[sc, 4] = (
            res[0], res[3], res[5], res[6], res[7])

