"""``study``: the paper's analytical study — bodies × records × signs × angles — on all cores.

Returns a :class:`StudyResult`: a tidy table (one row per scene) and its aggregation into the
controlled overturning rate COR = #(direction +1) / #(overturned) per body and angle, with counts.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from analysis import design
from analysis.body import Body, G
from analysis.envelope import block_bounds
from analysis.errors import AnalysisInputError
from analysis.simulate import (
    DEFAULT_FRICTION,
    DEFAULT_STEP,
    Criterion,
    Model,
    check_angle,
    check_dt,
    check_record,
    resolve_restitutions,
    substeps,
)


class RecordLike(Protocol):
    """What a study needs of a record (``rig.records.GroundMotion`` is one): its sample step ``dt`` [s] and
    accelerations in g (read only)."""

    @property
    def name(self) -> str: ...
    @property
    def dt(self) -> float: ...
    @property
    def acc_h(self) -> np.ndarray: ...
    @property
    def acc_v(self) -> np.ndarray | None: ...


STATUS = ("rest", "overturned", "undecided")
CHUNK = 16
"""Scenes a thread of the compiled batch takes at a time (dynamic scheduling: a thread slowed by other work on
the machine takes fewer, instead of the others waiting for its fixed share)."""


def _starts(sizes: np.ndarray) -> np.ndarray:
    """Where each of the consecutive pieces of ``sizes`` starts in their concatenation (int64)."""
    return np.concatenate(([0], np.cumsum(sizes)[:-1])).astype(np.int64)


def cor_counts(direction: np.ndarray) -> dict:
    """COR of a set of outcomes (docs/architecture.md §2): overturned, desired (+1) and their ratio (None
    when nothing overturned)."""
    over = int(np.count_nonzero(direction != 0))
    desired = int(np.count_nonzero(direction == 1))
    return {"overturned": over, "desired": desired, "cor": desired / over if over else None}


@dataclass
class StudyResult:
    """Scenes and their outcomes. Columns are arrays of one row per scene."""

    bodies: list[Body]
    records: list[str]
    angles: np.ndarray
    """Plate angles β [rad]."""
    signs: tuple[int, ...]
    model: str
    body: np.ndarray
    """Index into ``bodies`` per scene."""
    record: np.ndarray
    """Index into ``records`` per scene."""
    sign: np.ndarray
    """+1: the record as given along +x; −1: negated."""
    angle: np.ndarray
    """β [rad] per scene."""
    direction: np.ndarray
    t_overturn: np.ndarray
    """[s], NaN where no overturn."""
    theta_max: np.ndarray
    """[rad]"""
    impacts: np.ndarray
    status: np.ndarray
    """0 rest, 1 overturned, 2 undecided (see ``STATUS``)."""
    steps: np.ndarray
    """RK4 steps taken (0 for scenes the pre-screen settled)."""
    prescreened: np.ndarray
    seconds: float
    settings: dict = field(default_factory=dict)

    @property
    def scenes(self) -> int:
        return int(self.direction.size)

    def rows(self) -> list[dict]:
        """The tidy table as dicts (body label, record name, sign, angle_deg, outcome...)."""
        return [
            {
                "body": self.bodies[self.body[i]].label(),
                "record": self.records[self.record[i]],
                "sign": int(self.sign[i]),
                "angle_deg": round(math.degrees(float(self.angle[i])), 9),
                "direction": int(self.direction[i]),
                "t_overturn": None if math.isnan(self.t_overturn[i]) else float(self.t_overturn[i]),
                "theta_max": float(self.theta_max[i]),
                "status": STATUS[int(self.status[i])],
                "prescreened": bool(self.prescreened[i]),
            }
            for i in range(self.scenes)
        ]

    def cor(self) -> list[dict]:
        """COR per body and angle: counts of overturned and desired (+1) scenes; cor None if none."""
        out = []
        for j, body in enumerate(self.bodies):
            for beta in self.angles:
                sel = (self.body == j) & (self.angle == beta)
                out.append({
                    "body": body.label(), "b": body.b, "h": body.h,
                    "angle_deg": round(math.degrees(float(beta)), 9), "angle_rad": float(beta),
                    "scenes": int(np.count_nonzero(sel)), **cor_counts(self.direction[sel]),
                })
        return out

    def average_cor(self) -> list[dict]:
        """Per angle: the mean over bodies of their COR (bodies with no overturn left out), as the
        paper's Fig. 6, with the number of bodies averaged and the pooled counts."""
        rows = self.cor()
        out = []
        for beta in self.angles:
            at = [r for r in rows if r["angle_rad"] == float(beta)]
            defined = [r["cor"] for r in at if r["cor"] is not None]
            out.append({
                "angle_deg": round(math.degrees(float(beta)), 9), "angle_rad": float(beta),
                "cor": float(np.mean(defined)) if defined else None, "bodies": len(defined),
                "overturned": sum(r["overturned"] for r in at), "desired": sum(r["desired"] for r in at),
            })
        return out

    def fit_gcor(self) -> design.GcorFit:
        """Eq. 11 fitted to the body-averaged COR against angle."""
        avg = [r for r in self.average_cor() if r["cor"] is not None]
        return design.fit_gcor([r["angle_rad"] for r in avg], [r["cor"] for r in avg])

    def fit_scor(self) -> design.ScorFit:
        """Eq. 13's c1 = k1·b/h + k2·r + k3 fitted to every body's COR curve (weighted by counts)."""
        rows = [(r["b"], r["h"], r["angle_rad"], r["cor"], r["overturned"]) for r in self.cor()
                if r["cor"] is not None]
        return design.fit_scor(rows)

    def summary(self) -> dict:
        """JSON-ready summary as ``rig study --json`` prints it (docs/architecture.md §7)."""
        out: dict = {
            "model": self.model, "scenes": self.scenes, "seconds": round(self.seconds, 3),
            "prescreened": int(np.count_nonzero(self.prescreened)),
            "undecided": int(np.count_nonzero(self.status == 2)),
            "cor": self.cor(), "average_cor": self.average_cor(), "settings": self.settings,
        }
        avg = [r for r in self.average_cor() if r["cor"] is not None]
        beta = np.array([r["angle_rad"] for r in avg])
        observed = np.array([r["cor"] for r in avg])
        out["gcor_paper"] = {"c1": design.PAPER_GCOR[0], "c2": design.PAPER_GCOR[1],
                             "eq12_error": design.eq12_error(observed, design.gcor(beta)) if avg else None}
        try:
            fit = self.fit_gcor()
            out["gcor"] = {**fit.as_dict(), "eq12_error": design.eq12_error(observed, design.gcor(beta, *fit.coeffs))}
        except AnalysisInputError as exc:
            out["gcor"] = {"error": str(exc)}
        try:
            out["scor"] = self.fit_scor().as_dict()
        except AnalysisInputError as exc:
            out["scor"] = {"error": str(exc)}
        return out


def check_study_inputs(bodies: Sequence[Body], records: Sequence[RecordLike], angles: np.ndarray, model: str,
                       signs: Sequence[int], restitution: float | str, criterion: str) -> np.ndarray:
    """The checks of a study's arguments other than the records' samples (`checked_records`), before any work:
    model, non-empty bodies/records/angles [rad], signs, every body standing at every angle, criterion. Returns
    each body's coefficients of restitution (bodies, 2): at an impact ending rocking on the +x corner, and on the
    −x corner (``simulate.resolve_restitutions``); raises :class:`AnalysisInputError` naming what is wrong."""
    if model not in ("rocking", "general"):
        raise AnalysisInputError(f"model must be 'rocking' or 'general', got {model!r}")
    if not bodies or not records or angles.size == 0:
        raise AnalysisInputError("study needs at least one body, one record and one angle")
    if any(s not in (1, -1) for s in signs) or not signs:
        raise AnalysisInputError(f"signs must be drawn from (1, -1), got {tuple(signs)}")
    for body in bodies:
        for beta in angles:
            check_angle(body, float(beta))
    e = np.array([resolve_restitutions(b, restitution) for b in bodies]).reshape(len(bodies), 2)
    if criterion not in ("fall", "static"):
        raise AnalysisInputError(f"criterion must be 'fall' or 'static', got {criterion!r}")
    return e


def checked_records(records: Sequence[RecordLike], use_vertical: bool
                    ) -> list[tuple[np.ndarray, float, np.ndarray | None]]:
    """Each record's checked horizontal acceleration [g], step [s] and vertical acceleration [g] (None when it
    has none or ``use_vertical`` is off)."""
    out = []
    for rec in records:
        acc_h = check_record(rec.acc_h, f"record {rec.name}: acc_h")
        dt = check_dt(rec.dt)
        vert = rec.acc_v if (use_vertical and rec.acc_v is not None) else None
        out.append((acc_h, dt, check_record(vert, f"record {rec.name}: acc_v") if vert is not None else None))
    return out


def study(
    bodies: Sequence[Body],
    records: Sequence[RecordLike],
    angles: Sequence[float] | NDArray[np.float64],
    model: Model = "rocking",
    *,
    signs: Sequence[int] = (1, -1),
    restitution: float | str = 0.0,
    friction: float = DEFAULT_FRICTION,
    criterion: Criterion = "fall",
    t_after: float = 60.0,
    step: float = DEFAULT_STEP,
    use_vertical: bool = True,
    seed: int = 0,
) -> StudyResult:
    """Run every scene of bodies × records × signs × angles [rad] with the fast engine.

    Angles at which a body cannot stand (|β| ≥ α) are refused with the body and angle named.
    ``signs``: +1 the record as given along +x, −1 negated (the paper analyses both).
    ``use_vertical``: apply a record's vertical component when it has one.
    """
    angles_arr = np.asarray(angles, dtype=float)
    e = check_study_inputs(bodies, records, angles_arr, model, signs, restitution, criterion)

    # pack records: one series per (record, sign), trailing zero sample each, m/s²
    ax_parts, ay_parts, dts, has_v = [], [], [], []
    for acc_h, dt, vert in checked_records(records, use_vertical):
        acc_v = vert if vert is not None else np.zeros_like(acc_h)
        for sgn in signs:
            ax_parts.append(np.append(sgn * acc_h * G, 0.0))
            ay_parts.append(np.append(acc_v * G, 0.0))
            dts.append(dt)
            has_v.append(vert is not None)
    lengths = np.array([p.size for p in ax_parts], dtype=np.int64)
    offsets = _starts(lengths)
    ax = np.concatenate(ax_parts)
    ay = np.concatenate(ay_parts)
    dts_arr = np.array(dts)
    env_parts = [block_bounds(x, y) for x, y in zip(ax_parts, ay_parts, strict=True)]
    env = np.concatenate(env_parts)
    env_offsets = _starts(np.array([e_.shape[0] for e_ in env_parts], dtype=np.int64))
    n_series = len(dts)

    nb, nr, ns, na = len(bodies), len(records), len(signs), angles_arr.size
    j, q, a = np.meshgrid(np.arange(nb), np.arange(n_series), np.arange(na), indexing="ij")
    scene_body, scene_series, scene_angle = j.ravel(), q.ravel(), a.ravel()
    scene_beta = angles_arr[scene_angle]
    n_scenes = scene_body.size
    order = np.random.default_rng(seed).permutation(n_scenes)

    alpha_p, alpha_m = np.array([b.alpha_plus for b in bodies]), np.array([b.alpha_minus for b in bodies])
    r_p, r_m = np.array([b.r_plus for b in bodies]), np.array([b.r_minus for b in bodies])
    k_p, k_m = np.array([b.k_plus for b in bodies]), np.array([b.k_minus for b in bodies])
    ig2 = np.array([b.i_g**2 for b in bodies])
    e_p, e_m = np.ascontiguousarray(e[:, 0]), np.ascontiguousarray(e[:, 1])
    n_sub = np.array([[substeps(b, dt, step) for b in bodies] for dt in dts_arr], dtype=np.int64)
    out_f = np.full((n_scenes, 2), np.nan)
    out_i = np.zeros((n_scenes, 5), dtype=np.int64)
    static = criterion == "static"

    from numba import set_parallel_chunksize

    previous = set_parallel_chunksize(CHUNK)
    try:
        t0 = time.perf_counter()
        if model == "rocking":
            from analysis.batch import run_rocking

            run_rocking(ax, ay, offsets, lengths, env, env_offsets, dts_arr, scene_series, scene_body, scene_beta,
                        order, alpha_p, k_p, alpha_m, k_m, n_sub, e_p, e_m, float(t_after), static, out_f, out_i)
        else:
            from analysis.batch_general import run_general_kernel

            run_general_kernel(ax, ay, offsets, lengths, env, env_offsets, dts_arr, scene_series, scene_body,
                               scene_beta, order, alpha_p, r_p, alpha_m, r_m, ig2, n_sub, e_p, e_m, float(friction),
                               np.array(has_v), float(t_after), static, out_f, out_i)
        seconds = time.perf_counter() - t0
    finally:
        set_parallel_chunksize(previous)  # numba's setting is the process's: leave it as it was, also on an error

    signs_arr = np.array(signs)
    return StudyResult(
        bodies=list(bodies), records=[rec.name for rec in records], angles=angles_arr,
        signs=tuple(int(s) for s in signs), model=model,
        body=scene_body, record=scene_series // ns, sign=signs_arr[scene_series % ns], angle=scene_beta,
        direction=out_i[:, 0].astype(np.int8), t_overturn=out_f[:, 0], theta_max=out_f[:, 1],
        impacts=out_i[:, 1], status=out_i[:, 2].astype(np.int8), steps=out_i[:, 3],
        prescreened=out_i[:, 4].astype(bool), seconds=seconds,
        settings={"restitution": restitution, "friction": friction, "criterion": criterion,
                  "t_after": t_after, "step": step, "signs": list(signs), "records": nr},
    )
