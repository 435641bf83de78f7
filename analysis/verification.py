"""Fast engine against the reference solver, scene by scene, with a chaos check for disagreements.

A scene where the two disagree on the overturn direction is *chaotic* when a 1e-6 relative
perturbation of the input flips the reference's own answer too (the outcome is not determined by
the input to that precision); otherwise the disagreement is unexplained — a bug to fix.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from analysis.body import Body
from analysis.simulate import SimulationResult, simulate
from analysis.study import RecordLike, StudyResult, cor_counts, study

PERTURBATION = 1e-6


@dataclass
class SceneDifference:
    body: str
    record: str
    sign: int
    angle_deg: float
    fast: int
    reference: int
    reference_perturbed: tuple[int, int]
    """Reference directions with the input scaled by (1 + 1e-6) and (1 − 1e-6)."""
    chaotic: bool


@dataclass
class Agreement:
    """Scene-by-scene comparison of a fast study with the reference."""

    scenes: int
    same_direction: int
    cor_fast: list[dict]
    cor_reference: list[dict]
    max_cor_difference_pp: float
    """Largest |COR fast − COR reference| over (angle) of the body-pooled COR, in percentage points."""
    t_overturn_max_error: float
    """Largest |t_overturn fast − reference| [s] over scenes where both overturned the same way."""
    differences: list[SceneDifference] = field(default_factory=list)
    reference_seconds: float = 0.0
    fast_seconds: float = 0.0
    reference_direction: np.ndarray | None = None
    """Per scene, in the fast study's scene order."""
    reference_t_overturn: np.ndarray | None = None
    reference_theta_max: np.ndarray | None = None

    @property
    def fraction_same(self) -> float:
        return self.same_direction / self.scenes

    @property
    def unexplained(self) -> list[SceneDifference]:
        return [d for d in self.differences if not d.chaotic]


def _reference_scene(args: tuple) -> tuple[int, float, float]:
    body, acc_h, acc_v, dt, beta, model, kwargs = args
    res: SimulationResult = simulate(body, acc_h, dt, beta=beta, acc_v=acc_v, model=model, solver="reference",
                                     **kwargs)
    return res.direction, (math.nan if res.t_overturn is None else res.t_overturn), res.theta_max


def _pooled_cor(direction: np.ndarray, angle: np.ndarray, angles: np.ndarray) -> list[dict]:
    out = []
    for beta in angles:
        out.append({"angle_deg": round(math.degrees(float(beta)), 9), **cor_counts(direction[angle == beta])})
    return out


def compare_with_reference(
    bodies: Sequence[Body],
    records: Sequence[RecordLike],
    angles: Sequence[float],
    model: str = "rocking",
    *,
    processes: int | None = None,
    **kwargs: object,
) -> Agreement:
    """Run the study with the fast engine and every scene with the reference (in ``processes``
    worker processes, default all cores); check every disagreement for chaos."""
    import time

    fast: StudyResult = study(bodies, records, angles, model=model, **kwargs)  # type: ignore[arg-type]
    sim_kwargs = {k: v for k, v in kwargs.items() if k in ("restitution", "friction", "criterion", "t_after")}

    def scene_args(i: int, scale: float = 1.0) -> tuple:
        rec = records[fast.record[i]]
        sgn = int(fast.sign[i])
        return (fast.bodies[fast.body[i]], sgn * scale * np.asarray(rec.acc_h), rec.acc_v, rec.dt,
                float(fast.angle[i]), model, sim_kwargs)

    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=processes or os.cpu_count() or 1) as pool:
        ref = list(pool.map(_reference_scene, (scene_args(i) for i in range(fast.scenes)), chunksize=16))
        ref_dir = np.array([r[0] for r in ref])
        ref_t = np.array([r[1] for r in ref])
        ref_theta = np.array([r[2] for r in ref])
        ref_seconds = time.perf_counter() - t0
        diff_idx = np.flatnonzero(ref_dir != fast.direction)
        perturbed = list(pool.map(_reference_scene, [scene_args(i, s) for i in diff_idx
                                                    for s in (1 + PERTURBATION, 1 - PERTURBATION)]))
    differences = []
    for n, i in enumerate(diff_idx):
        pert = (perturbed[2 * n][0], perturbed[2 * n + 1][0])
        differences.append(SceneDifference(
            body=fast.bodies[fast.body[i]].label(), record=fast.records[fast.record[i]], sign=int(fast.sign[i]),
            angle_deg=round(math.degrees(float(fast.angle[i])), 9), fast=int(fast.direction[i]),
            reference=int(ref_dir[i]), reference_perturbed=pert,
            chaotic=any(p != ref_dir[i] for p in pert)))
    angles_arr = np.asarray(angles, dtype=float)
    cor_f = _pooled_cor(fast.direction, fast.angle, angles_arr)
    cor_r = _pooled_cor(ref_dir, fast.angle, angles_arr)
    gaps = [abs(a["cor"] - b["cor"]) * 100 for a, b in zip(cor_f, cor_r, strict=True)
            if a["cor"] is not None and b["cor"] is not None]
    both = (ref_dir == fast.direction) & (ref_dir != 0)
    t_err = np.abs(fast.t_overturn[both] - ref_t[both])
    return Agreement(
        scenes=fast.scenes, same_direction=int(np.count_nonzero(ref_dir == fast.direction)),
        cor_fast=cor_f, cor_reference=cor_r, max_cor_difference_pp=max(gaps, default=0.0),
        t_overturn_max_error=float(t_err.max()) if t_err.size else 0.0, differences=differences,
        reference_seconds=ref_seconds, fast_seconds=fast.seconds, reference_direction=ref_dir,
        reference_t_overturn=ref_t, reference_theta_max=ref_theta)
