"""`analyze_session`: the paper's models re-run on every run's *measured* plate motion, predictions beside
observations, and the Fig. 13 comparison (docs/architecture.md §4; the paper's EXPERIMENTAL RESULTS).

For every ``completed`` run (others are skipped and listed with their status: ``aborted``, ``interrupted``,
``refused``, ``skipped``, ``running``): the run's accelerometer samples → the models' input
(`rig.analyze.transform`), then every body of the run's ``bodies`` table and every model through
``analysis.simulate`` at the run's angle (plastic impacts and the general model's default high friction, as in
the paper's analysis; ``restitution`` can change the impact rule, ``"fit"`` identifies each body's from its
measured tilts: `rig.analyze.restitution`; ``"all"`` runs the models under the three impact rules
:data:`IMPACT_RULES`, plastic, Housner's and fitted, side by side: each model under each rule is one analysis,
labelled ``model:rule``, e.g. ``rocking:fit``, wherever a model's name stands — predictions, Fig. 13 rows,
agreement). The observed direction of a body is its first detection in the run (sensor or operator), 0 if none.
The Fig. 13 table and its COR definition: `rig.analyze.fig13`; the file layout: `rig.analyze.store`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from analysis import AnalysisInputError, Body, simulate
from analysis.agreement import MARGIN
from analysis.simulate import resolve_restitution
from analysis.table.configuration import configuration_from_dict
from analysis.table.sensors import clipped_rows
from rig.sequence import record_of_label
from rig.session import checksums, read_session

from . import fig13, store
from .fig13 import rule_label
from .restitution import BodyRestitution, fitted_restitution
from .results import Agreement, Prediction, RunAnalysis, SessionAnalysis, SkippedRun
from .transform import TransformError, measured_inputs

MODELS = ("rocking", "general")
SOLVERS = ("fast", "reference")
ANALYSED_STATUSES = frozenset({"completed"})
"""Run statuses analysed by default (``degraded`` runs only when asked)."""

ALL_RULES = "all"
"""``restitution`` value that runs every model under each of :data:`IMPACT_RULES`."""

IMPACT_RULES = ("plastic", "housner", "fit")
"""The impact rules of ``restitution = "all"``, in the order they are shown: plastic (restitution 0, the
paper's analysis), Housner's 1 − 1.5 sin²α, and each body's fitted from its measured tilts."""



def observed_directions(detections: list[dict[str, Any]]) -> dict[int, tuple[int, float]]:
    """{body_id: (direction, t)} from a run's detections: each body's first overturn (by time; an operator's
    answer, without a time, after the timed ones). Rows with direction 0 say "did not overturn" and are skipped."""
    def key(row: dict[str, Any]) -> tuple[bool, float]:
        t = float(row["t"])
        return (math.isnan(t), 0.0 if math.isnan(t) else t)

    out: dict[int, tuple[int, float]] = {}
    for row in sorted(detections, key=key):
        direction = int(row["direction"])
        if direction and int(row["body_id"]) not in out:
            out[int(row["body_id"])] = (direction, float(row["t"]))
    return out


def body_of(row: dict[str, Any]) -> Body:
    """A session ``bodies`` row → `analysis.Body` (depth, mass and the centre of gravity b_cg, h_cg carried when
    given; else the middle: the uniform block, as in files written before they were recorded)."""
    def optional(value: Any) -> float | None:
        v = float(value)
        return v if math.isfinite(v) and v > 0 else None

    return Body(b=float(row["b"]), h=float(row["h"]), depth=optional(row["depth"]), mass=optional(row["mass"]),
                name=str(row.get("name", "")), b_cg=optional(row.get("b_cg", math.nan)),
                h_cg=optional(row.get("h_cg", math.nan)))


def analyze_run(run: dict[str, Any], models: Sequence[str], solver: str, sensor: str | None = None,
                restitution: float | str | Mapping[int, float] = 0.0) -> RunAnalysis:
    """One run (as `rig.session.read_session` returns it) → its predictions. ``restitution``: one impact rule for
    every body, or {body_id: restitution}. `TransformError` if it has no usable accelerometer samples."""
    angle_deg = float(run["angle_deg"])
    beta = math.radians(angle_deg)
    inp = measured_inputs(run["accel"], beta, sensor)
    inp = replace(inp, notes=(*inp.notes, *checksums.notes(run.get("checksums"))))
    observed = observed_directions(run["detections"])
    predictions: list[Prediction] = []
    skipped: list[tuple[int, str]] = []
    for row in run["bodies"]:
        body_id = int(row["body_id"])
        seen, t_seen = observed.get(body_id, (0, math.nan))
        try:
            body = body_of(row)
            impact = restitution.get(body_id, "housner") if isinstance(restitution, Mapping) else restitution
            for model in models:
                res = simulate(body, inp.acc_h, inp.dt, beta=beta, acc_v=inp.acc_v, restitution=impact,
                               model=model,  # type: ignore[arg-type]  # a str: simulate refuses a bad one
                               solver=solver)  # type: ignore[arg-type]  # a str: simulate refuses a bad one
                t_over = math.nan if res.t_overturn is None else inp.t0 + res.t_overturn
                predictions.append(Prediction(run["name"], body_id, body.name, model, res.direction, t_over,
                                              res.theta_max, res.status, seen, t_seen))
        except AnalysisInputError as exc:
            skipped.append((body_id, str(exc)))
    return RunAnalysis(run["name"], str(run["record"]), angle_deg, inp, predictions, skipped)


def _analyze(session: dict[str, Any], path: Path, models: tuple[str, ...], solver: str, sensor: str | None,
             restitution: float | str, margin: float, written: bool, include_degraded: bool = False
             ) -> SessionAnalysis:
    runs: list[RunAnalysis] = []
    skipped: list[SkippedRun] = []
    fitted: dict[int, BodyRestitution] = {}
    if restitution in ("fit", ALL_RULES):
        fitted = fitted_restitution(session["runs"])
    rule_of: dict[str, float | str | dict[int, float]] = {
        "plastic": 0.0, "housner": "housner", "fit": {body_id: body.value for body_id, body in fitted.items()}}
    rules: dict[str, float | str | dict[int, float]] = (
        {rule: rule_of[rule] for rule in IMPACT_RULES} if restitution == ALL_RULES
        else {"": rule_of["fit"] if restitution == "fit" else restitution})
    analysed = ANALYSED_STATUSES | ({"degraded"} if include_degraded else set())
    ranges = full_scales(session.get("rig_config"), path)
    for run in session["runs"]:
        status = str(run["status"])
        if status not in analysed:
            if status == "degraded":
                reason = (f"degraded ({run['attrs'].get('degraded') or 'see its events'}): left out of Fig. 13 "
                          "(rig analyze --include-degraded takes it)")
            else:
                reason = run["attrs"].get("reason") or f"status {status}: only completed runs are analysed"
            skipped.append(SkippedRun(run["name"], status, str(reason)))
            continue
        try:
            done = _analyze_rules(run, models, solver, sensor, rules)
            runs.append(replace(done, clipped={name: len(clipped_rows(run["accel"][name][:, 1:], ranges[name]))
                                               for name in run["accel"] if name in ranges}))
        except TransformError as exc:
            skipped.append(SkippedRun(run["name"], status, str(exc)))
    labels = tuple(rule_label(m, rule) if rule else m for m in models for rule in rules)
    predictions = [p for r in runs for p in r.predictions]
    angle = {r.run: r.angle_deg for r in runs}
    record = {r.run: record_of_label(r.record)[0] for r in runs}  # both polarities of a record: one cluster
    cases = [fig13.Case(angle[p.run], p.body_id, p.model, p.direction, p.observed, record[p.run])
             for p in predictions]
    rows = fig13.fig13_rows(cases, margin)
    diff = fig13.max_difference(rows)
    return SessionAnalysis(
        path=str(path), models=labels, solver=solver, restitution=str(restitution), fitted_restitution=fitted,
        runs=runs, skipped=skipped, margin=margin,
        fig13=rows, max_difference={m: diff.get(m) for m in labels},
        agreement={m: Agreement.of(m, predictions) for m in labels}, written=written)


def full_scales(rig_config: Any, path: Path) -> dict[str, float]:
    """{sensor: full scale [m/s²]} of the accelerometers with a calibration sheet in a session's stored rig
    configuration (``[sensors]``, ``analysis.table.sensors``)."""
    stored = rig_config.get("sensors") if isinstance(rig_config, Mapping) else None
    if stored is None:
        return {}
    sheets = configuration_from_dict({"sensors": stored}, source=f"{path}: rig_config").sensors
    return {name: sheet.range_m_s2 for name, sheet in sheets.sheets.items()}


def _analyze_rules(run: dict[str, Any], models: Sequence[str], solver: str, sensor: str | None,
                   rules: Mapping[str, float | str | Mapping[int, float]]) -> RunAnalysis:
    """`analyze_run` under each of ``rules`` ({rule: restitution}; one rule "" keeps the models' plain names),
    the predictions of all in one `RunAnalysis`, each labelled `rig.analyze.fig13.rule_label`."""
    done = [(rule, analyze_run(run, models, solver, sensor, impact)) for rule, impact in rules.items()]
    if len(done) == 1:
        return done[0][1]
    first = done[0][1]
    predictions = [replace(p, model=rule_label(p.model, rule)) for rule, ra in done for p in ra.predictions]
    skipped = list(dict.fromkeys(body for _, ra in done for body in ra.skipped_bodies))
    return replace(first, predictions=predictions, skipped_bodies=skipped)


def analyze_session(path: str | os.PathLike[str], models: Sequence[str] = MODELS, solver: str = "fast", *,
                    sensor: str | None = None, restitution: float | str = 0.0, margin: float = MARGIN,
                    write: bool = True, include_degraded: bool = False) -> SessionAnalysis:
    """Re-run ``models`` (``"rocking"``, ``"general"``) with ``solver`` (``"fast"``/``"reference"``) on every
    completed run of the session file at ``path`` (module docstring) and, with ``write``, store the result in its
    ``analysis`` groups, replacing earlier ones (`rig.analyze.store`; raw data untouched).

    ``sensor``: use that accelerometer only (default: the mean of all). ``restitution``: the models' impact rule,
    0 (plastic, the paper's analysis: default), ``"housner"`` (1 − 1.5 sin²α, a rigid block's no-bounce impact)
    a number in [0, 1], ``"fit"``: each body's from the session's measured tilts (`rig.analyze.restitution`;
    a body that hardly rocked gets Housner's), or ``"all"``: the three side by side (module docstring).
    ``margin``: the equivalence margin of the Fig. 13 verdicts [fraction, 0.05 = 5 points]. ``include_degraded``:
    also the runs logged ``degraded`` (left out by default, each listed in ``skipped`` with what degraded it).
    Raises `AnalysisInputError` for a bad model/solver/restitution, `rig.session.SessionError` for a file that
    cannot be read or (with ``write``) is being written (`rig.analyze.store.SessionBusyError`).
    """
    models = tuple(dict.fromkeys(models))
    if not models or any(m not in MODELS for m in models):
        raise AnalysisInputError(f"models {list(models)!r}: expected one or both of {list(MODELS)}")
    if solver not in SOLVERS:
        raise AnalysisInputError(f"solver {solver!r}: expected one of {list(SOLVERS)}")
    if not 0.0 < margin < 1.0:
        raise AnalysisInputError(f"margin {margin!r}: expected a fraction in (0, 1) (0.05 = 5 points)")
    if restitution not in ("fit", ALL_RULES):
        resolve_restitution(Body(b=0.1, h=0.5), restitution)  # a bad value fails here, not as skipped bodies
    path = Path(path)
    if not write:
        return _analyze(read_session(path), path, models, solver, sensor, restitution, margin, written=False,
                        include_degraded=include_degraded)
    with store.locked(path) as file:
        result = _analyze(read_session(path), path, models, solver, sensor, restitution, margin, written=True,
                          include_degraded=include_degraded)
        store.write(file, result)
    return result
