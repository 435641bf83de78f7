"""Fast engine against the reference solver, scene by scene, with a chaos check for disagreements.

A scene where the two disagree on the overturn direction is *chaotic* when a 1e-6 relative
perturbation of the input flips the reference's own answer too (the outcome is not determined by
the input to that precision); otherwise the disagreement is unexplained — a bug to fix.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from analysis.body import Body
from analysis.simulate import Model, SimulationResult, simulate
from analysis.study import RecordLike, cor_counts, study

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
    model: Model = "rocking",
    *,
    processes: int | None = None,
    **kwargs: object,
) -> Agreement:
    """Run the study with the fast engine and every scene with the reference (in ``processes``
    worker processes, default all cores); check every disagreement for chaos."""
    import time

    fast = study(bodies, records, angles, model=model,
                 **kwargs)  # type: ignore[arg-type]  # kwargs: study's own options, checked there
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
        perturbed = list(pool.map(_reference_scene, [scene_args(int(i), s) for i in diff_idx
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


# --------------------------------------------------------------------------------------------------
# the stressed set: friction that slides, vertical input that throws, both signs, steep angles


@dataclass
class StressedScene:
    """One scene of the general model's stressed agreement set (accelerations in g, β in rad)."""

    body: Body
    record: str
    acc_h: np.ndarray
    acc_v: np.ndarray | None
    dt: float
    beta: float
    friction: float


def stressed_scenes(bodies: Sequence[Body], records: Sequence[RecordLike], n: int, seed: int) -> list[StressedScene]:
    """``n`` seeded random scenes: a body and a record (either sign), β uniform in [0°, 10°] (below
    each body's α), μ uniform in [0.1, 0.6], and in half of them a vertical input: the record's
    partner component (``records[i ^ 1]``: the FEMA P695 set lists each station's two horizontals in
    a row), cut or zero-padded to length and scaled to a peak uniform in [0.3, 1.5] g: where it
    exceeds g downwards, g_z < 0 and the block flies."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        body = bodies[int(rng.integers(len(bodies)))]
        i = int(rng.integers(len(records)))
        rec = records[i]
        acc_h = float(rng.choice([1.0, -1.0])) * np.asarray(rec.acc_h, dtype=float)
        beta = min(math.radians(float(rng.uniform(0.0, 10.0))), 0.95 * body.alpha_plus)
        mu = float(rng.uniform(0.1, 0.6))
        acc_v = None
        if rng.random() < 0.5:
            partner = np.asarray(records[i ^ 1 if (i ^ 1) < len(records) else i].acc_h, dtype=float)
            acc_v = np.zeros(acc_h.size)
            m = min(acc_v.size, partner.size)
            acc_v[:m] = partner[:m]
            acc_v *= float(rng.uniform(0.3, 1.5)) / max(float(np.max(np.abs(acc_v))), 1e-300)
        out.append(StressedScene(body, rec.name, acc_h, acc_v, float(rec.dt), beta, mu))
    return out


@dataclass
class StressedAgreement:
    """Fast engine against the reference on :func:`stressed_scenes`."""

    scenes: int
    same_outcome: int
    """Scenes with the same direction (and status) in both."""
    overturned: int
    """Scenes the reference overturned."""
    sliding: int
    """Scenes in which the reference slid (slide_time > 0)."""
    with_vertical: int
    unexplained: list[dict]
    """Differing scenes that a 1e-6 perturbation of the input does not flip in the reference."""
    chaotic: int
    slide_residual_max_error_m: float
    """Largest |u_end fast − reference| [m] over scenes with the same outcome that came to rest."""
    slide_peak_max_error_m: float
    slide_time_max_error_s: float
    t_overturn_max_error_s: float
    reference_seconds: float


class _StressedOutcome(NamedTuple):
    """What the stressed agreement compares of one scene (t_overturn NaN when the body did not overturn)."""

    direction: int
    status: str
    t_overturn: float
    slide_peak: float
    slide_residual: float
    slide_time: float

    @classmethod
    def of(cls, res: SimulationResult) -> _StressedOutcome:
        return cls(res.direction, res.status, math.nan if res.t_overturn is None else res.t_overturn, res.slide_peak,
                   res.slide_residual, res.slide_time)


def _stressed_reference(args: tuple[StressedScene, float]) -> _StressedOutcome:
    sc, scale = args
    res = simulate(sc.body, scale * sc.acc_h, sc.dt, beta=sc.beta, acc_v=None if sc.acc_v is None else scale * sc.acc_v,
                   model="general", solver="reference", friction=sc.friction)
    return _StressedOutcome.of(res)


def compare_stressed(scenes: Sequence[StressedScene], *, processes: int | None = None) -> StressedAgreement:
    """Every scene through both engines (the reference in ``processes`` workers); a differing outcome
    is checked for chaos as :func:`compare_with_reference` does."""
    import time

    fast: list[_StressedOutcome] = []
    for sc in scenes:
        res = simulate(sc.body, sc.acc_h, sc.dt, beta=sc.beta, acc_v=sc.acc_v, model="general", friction=sc.friction)
        fast.append(_StressedOutcome.of(res))
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=processes or os.cpu_count() or 1) as pool:
        ref = list(pool.map(_stressed_reference, [(sc, 1.0) for sc in scenes], chunksize=4))
        ref_seconds = time.perf_counter() - t0
        diff = [i for i in range(len(scenes)) if fast[i][:2] != ref[i][:2]]
        pert = list(pool.map(_stressed_reference, [(scenes[i], s) for i in diff
                                                   for s in (1 + PERTURBATION, 1 - PERTURBATION)]))
    unexplained = []
    for n_, i in enumerate(diff):
        if all(p[:2] == ref[i][:2] for p in pert[2 * n_:2 * n_ + 2]):
            sc = scenes[i]
            unexplained.append({"body": sc.body.label(), "record": sc.record, "beta_deg": math.degrees(sc.beta),
                                "friction": sc.friction, "vertical": sc.acc_v is not None,
                                "fast": fast[i][:2], "reference": ref[i][:2]})
    same = [i for i in range(len(scenes)) if fast[i][:2] == ref[i][:2]]
    rest = [i for i in same if ref[i][1] == "rest"]
    over = [i for i in same if ref[i][0] != 0]

    def worst(idx: list[int], value: Callable[[_StressedOutcome], float]) -> float:
        return max((abs(value(fast[i]) - value(ref[i])) for i in idx), default=0.0)

    return StressedAgreement(
        scenes=len(scenes), same_outcome=len(same), overturned=sum(r[0] != 0 for r in ref),
        sliding=sum(r.slide_time > 0.0 for r in ref), with_vertical=sum(sc.acc_v is not None for sc in scenes),
        unexplained=unexplained, chaotic=len(diff) - len(unexplained),
        slide_residual_max_error_m=worst(rest, lambda o: o.slide_residual),
        slide_peak_max_error_m=worst(rest, lambda o: o.slide_peak),
        slide_time_max_error_s=worst(rest, lambda o: o.slide_time),
        t_overturn_max_error_s=worst(over, lambda o: o.t_overturn), reference_seconds=ref_seconds)


# --------------------------------------------------------------------------------------------------
# free rocking with e = 1: how much energy the fast engine's RK4 adds


def free_rocking_energy_growth(body: Body, amplitude: float, *, step: float, model: Model = "general",
                               t_free: float = 60.0) -> float:
    """Relative energy gained in ``t_free`` seconds of free rocking with e = 1 (no loss at impact) on
    a level plate, released from rest at θ0 = ``amplitude`` [rad], fast engine at ``step`` (p·h). For a body whose
    two corners are alike (``Body.symmetric``: an off-centre one returns to a different amplitude on its other side,
    V15).

    The exact motion keeps its energy, k g cos(α − |θ|) + ω²/2 per unit of i_g² + r²: every half
    cycle returns to |θ| = θ0. The figure is the potential energy above rest at the largest |θ| the
    engine reached over that at θ0, minus 1: (cos(α − θ_max) − cos(α − θ0)) / (cos(α − θ0) − cos α);
    0 when it never rose above θ0 (energy lost, not gained, is not counted here)."""
    res = simulate(body, np.zeros(2), 0.01, model=model, restitution=1.0, theta0=amplitude, t_after=t_free,
                   step=step)
    a = body.alpha
    return (math.cos(a - res.theta_max) - math.cos(a - amplitude)) / (math.cos(a - amplitude) - math.cos(a))
