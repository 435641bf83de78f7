"""What `rig.analyze.analyze_session` returns: predictions beside observations, per run and for the session.

Directions everywhere: +1 overturned towards the low side (+x, the desired side), −1 towards the high side,
0 did not overturn (docs/architecture.md §2). Times in seconds on the run's clock (from the drive's first sample);
NaN when there is none (``null`` in JSON). Angles θ in rad, plate angles in degrees.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

from .fig13 import Fig13Row, verdict_counts
from .restitution import BodyRestitution
from .transform import ModelInput


def _clean(value: Any) -> Any:
    """NaN → None, recursively (JSON has no NaN)."""
    if isinstance(value, float) and math.isnan(value):
        return None
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    return value


@dataclass(frozen=True)
class Prediction:
    """One body in one run by one model, beside what the table's detector (or the operator) saw."""

    run: str
    body_id: int
    body_name: str
    model: str
    direction: int
    """Predicted: +1 low side, −1 high side, 0 none."""
    t_overturn: float
    """Predicted overturn time [s, run clock] (|θ| reaches π/2), NaN if none."""
    theta_max: float
    """Largest predicted |θ| relative to the plate [rad]."""
    status: str
    """The model's end state: ``overturned``, ``rest`` or ``undecided``."""
    observed: int
    """Observed direction (first detection of the body in the run), 0 if it was not seen to overturn."""
    t_observed: float
    """Time of that detection [s, run clock]; NaN if none (or an operator's answer, which has no time)."""

    def to_json(self) -> dict[str, Any]:
        return _clean(asdict(self))


@dataclass(frozen=True)
class RunAnalysis:
    """One completed run: its model input (from the measured motion) and the predictions."""

    run: str
    record: str
    angle_deg: float
    input: ModelInput
    predictions: list[Prediction]
    skipped_bodies: list[tuple[int, str]] = field(default_factory=list)
    """(body_id, reason) of bodies the models could not take (e.g. one that cannot stand at this angle)."""
    clipped: dict[str, int] = field(default_factory=dict)
    """Samples per accelerometer (those with a calibration sheet) at or beyond its full scale: the models were given
    a cut signal there."""

    def to_json(self) -> dict[str, Any]:
        inp = self.input
        return _clean({
            "run": self.run, "record": self.record, "angle_deg": self.angle_deg,
            "input": {"dt": inp.dt, "t0": inp.t0, "duration": inp.duration, "samples": int(inp.acc_h.size),
                      "sensors": list(inp.sensors), "resampled": inp.resampled, "gaps": inp.gaps,
                      "longest_gap": inp.longest_gap, "notes": list(inp.notes),
                      "peak_acc_h_g": float(abs(inp.acc_h).max()), "peak_acc_v_g": float(abs(inp.acc_v).max())},
            "predictions": [p.to_json() for p in self.predictions],
            "skipped_bodies": [{"body_id": b, "reason": r} for b, r in self.skipped_bodies],
            "clipped": dict(self.clipped),
        })


@dataclass(frozen=True)
class SkippedRun:
    """A run not analysed: its status and why."""

    run: str
    status: str
    reason: str

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class Agreement:
    """Case by case (body × run), predicted against observed, for one model.

    ``agree``: same direction, 0 included; ``overturned_both``/``analysis_only``/``experiment_only``/``neither``
    split the cases by who saw an overturn; ``same_direction``: of ``overturned_both``, those with the same side.
    ``confusion``: {predicted: {observed: count}} with keys "+1", "0", "-1".
    """

    model: str
    cases: int
    agree: int
    overturned_both: int
    overturned_analysis_only: int
    overturned_experiment_only: int
    overturned_neither: int
    same_direction: int
    confusion: dict[str, dict[str, int]]

    @classmethod
    def of(cls, model: str, predictions: list[Prediction]) -> Agreement:
        """Count the cases of ``model`` in ``predictions``."""
        cases = [(p.direction, p.observed) for p in predictions if p.model == model]
        keys = ("+1", "0", "-1")
        confusion = {k: dict.fromkeys(keys, 0) for k in keys}
        for pred, obs in cases:
            confusion[f"{pred:+d}" if pred else "0"][f"{obs:+d}" if obs else "0"] += 1
        return cls(
            model=model, cases=len(cases), agree=sum(1 for p, o in cases if p == o),
            overturned_both=sum(1 for p, o in cases if p and o),
            overturned_analysis_only=sum(1 for p, o in cases if p and not o),
            overturned_experiment_only=sum(1 for p, o in cases if o and not p),
            overturned_neither=sum(1 for p, o in cases if not p and not o),
            same_direction=sum(1 for p, o in cases if p and o and p == o),
            confusion=confusion,
        )

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class SessionAnalysis:
    """Everything `analyze_session` found (and, with ``written``, stored in the session file's ``analysis``
    groups). ``max_difference``: per model, the largest |COR difference| of a body at an angle (None: no COR
    defined on both sides anywhere)."""

    path: str
    models: tuple[str, ...]
    solver: str
    restitution: str
    """The models' impact rule as given: ``"0.0"`` (plastic, the paper's), ``"housner"``, a number, ``"fit"``, or
    ``"all"`` (the three rules side by side: ``models`` then holds the labels ``model:rule``,
    `rig.analyze.fig13.rule_label`)."""
    fitted_restitution: dict[int, BodyRestitution]
    """With ``"fit"`` or ``"all"``: each body's restitution and where it came from (empty otherwise)."""
    runs: list[RunAnalysis]
    skipped: list[SkippedRun]
    margin: float
    """The equivalence margin of the Fig. 13 verdicts [fraction]."""
    fig13: list[Fig13Row]
    max_difference: dict[str, float | None]
    agreement: dict[str, Agreement]
    written: bool

    @property
    def verdicts(self) -> dict[str, dict[str, int]]:
        """Per model, how many body-angle rows got each equivalence verdict (`rig.analyze.fig13.VERDICTS`)."""
        return verdict_counts(self.fig13)

    @property
    def predictions(self) -> list[Prediction]:
        """Every prediction of every analysed run."""
        return [p for run in self.runs for p in run.predictions]

    def to_json(self) -> dict[str, Any]:
        """The ``rig analyze --json`` object."""
        return _clean({
            "path": self.path, "models": list(self.models), "solver": self.solver, "restitution": self.restitution,
            "fitted_restitution": [b.to_json() for b in self.fitted_restitution.values()],
            "written": self.written,
            "runs": [r.to_json() for r in self.runs], "skipped": [s.to_json() for s in self.skipped],
            "fig13": [r.to_json() for r in self.fig13], "max_difference": self.max_difference,
            "agreement": {m: a.to_json() for m, a in self.agreement.items()},
            "margin": self.margin, "verdicts": self.verdicts,
        })
