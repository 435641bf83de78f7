"""The compiled batch for the general model (see :mod:`analysis.batch`)."""

from __future__ import annotations

import numpy as np
from numba import prange

from analysis.batch import fall_angles
from analysis.compiled_index import njit
from analysis.envelope import BLOCK
from analysis.fast_general import simulate_general


@njit(cache=True, parallel=True)
def run_general_kernel(
    ax: np.ndarray, ay: np.ndarray, offsets: np.ndarray, lengths: np.ndarray, env: np.ndarray,
    env_offsets: np.ndarray, dts: np.ndarray,
    scene_series: np.ndarray, scene_body: np.ndarray, scene_beta: np.ndarray, order: np.ndarray,
    alpha_p: np.ndarray, r_p: np.ndarray, alpha_m: np.ndarray, r_m: np.ndarray, ig2: np.ndarray, n_sub: np.ndarray,
    e_p: np.ndarray, e_m: np.ndarray, mu: float, has_vertical: np.ndarray, t_after: float, static: bool,
    out_f: np.ndarray, out_i: np.ndarray,
) -> None:
    """General model for every scene (per body the two corners, ``simulate_general``); outputs as
    :func:`analysis.batch.run_rocking`."""
    for idx in prange(order.shape[0]):
        sc = order[idx]
        q, j, beta = scene_series[sc], scene_body[sc], scene_beta[sc]
        a, c = offsets[q], env_offsets[q]
        n_env = (lengths[q] + BLOCK - 1) // BLOCK
        fp, fm = fall_angles(static, alpha_p[j], alpha_m[j], beta)
        res = simulate_general(ax[a:a + lengths[q]], ay[a:a + lengths[q]], env[c:c + n_env], dts[q], alpha_p[j],
                               r_p[j], alpha_m[j], r_m[j], ig2[j], beta, e_p[j], e_m[j], mu, n_sub[q, j], t_after, fp,
                               fm, 0.0, 0.0, has_vertical[q])
        out_f[sc, 0], out_f[sc, 1] = res[1], res[2]
        out_i[sc, 0], out_i[sc, 1], out_i[sc, 2], out_i[sc, 3], out_i[sc, 4] = (
            res[0], res[3], res[5], res[6], res[7])
