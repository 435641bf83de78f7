"""What a sequence can show before it runs: the analytical study of its bodies, angles and records as the table will
play them, the overturns to expect per body and angle, and the runs an equivalence verdict needs (``rig plan``).

**The study.** Every record of the sequence is prepared at every angle as `Sequence.prepare` prepares it for the
table (scale policy, window, high-pass, polarity) and its commanded plate acceleration — surge [m/s²] horizontal,
+ towards the low side; heave vertical, + up; both / G — goes to the fast engine (`analysis.study.study`) with every
body of the sequence at that angle, in one sign (the polarity is already in the drive). The model and impact rule
are those `rig analyze` re-runs (default: the rocking model with plastic impacts, the paper's analysis). A
record's repetitions replay the same drive: the model's outcome is the same, so its overturns count once per
repetition.

**The runs needed.** Per body and angle the expected COR p of the study is taken as the rate both analysis and
experiment would show (the hope of the campaign), and `analysis.agreement.cases_for_power` gives the overturns n
on each side at which the equivalence test of Fig. 13 (`rig analyze`) calls them equivalent within ``margin``
with probability ``power``; with a fraction f of the runs overturning the body, that is n / f runs of it at that
angle, and ``repetitions`` = ⌈runs / (records × polarities)⌉ passes over the sequence's records. A body the study
never overturns at an angle has no COR there and no number of runs gives it one. The test treats analysis and
experiment as independent samples (conservative for records they share): the numbers are an upper bound of what a
paired test would need.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.agreement import MARGIN, cases_for_power
from analysis.body import G
from analysis.study import study

from .model import PlannedRun
from .sequence import Sequence

POWER = 0.8
"""The default probability that the equivalence test calls a right analysis equivalent."""


@dataclass(frozen=True)
class PlayedMotion:
    """A drive's commanded plate motion as the models take it (`analysis.study.RecordLike`): accelerations in g."""

    name: str
    dt: float
    acc_h: np.ndarray
    acc_v: np.ndarray | None


@dataclass(frozen=True)
class BodyPlan:
    """One body at one angle: the study's outcome over the sequence's runs and the runs its verdict needs.

    ``runs``: runs of the sequence at this angle (records × polarities × repetitions); ``overturned`` and
    ``towards_low`` among them (expected); ``cor`` towards_low / overturned (None without an overturn);
    ``overturns_needed`` on each side for the equivalence test to reach the power, ``runs_needed`` the runs at this
    angle that give them, ``repetitions_needed`` the passes over the records (None: never, the body does not
    overturn or its rate cannot be resolved within the search's limit).
    """

    angle_deg: float
    body_id: int
    name: str
    runs: int
    overturned: int
    towards_low: int
    cor: float | None
    overturns_needed: int | None
    runs_needed: int | None
    repetitions_needed: int | None

    def to_json(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass(frozen=True)
class SequencePlan:
    """``rig plan``'s answer: the settings and one `BodyPlan` per body and angle, in the sequence's order."""

    sequence: str
    model: str
    restitution: str
    margin: float
    power: float
    records: int
    """Entries of the sequence's records (a record in both polarities counts twice)."""
    repetitions: int
    bodies: list[BodyPlan]

    def to_json(self) -> dict[str, Any]:
        by_angle: dict[float, list[BodyPlan]] = {}
        for body in self.bodies:
            by_angle.setdefault(body.angle_deg, []).append(body)
        angles = []
        for angle, rows in by_angle.items():
            needed = [r.runs_needed for r in rows if r.cor is not None]
            known = [n for n in needed if n is not None]
            angles.append({"angle_deg": angle, "runs": rows[0].runs,
                           "runs_needed_for_every_body": max(known) if needed and len(known) == len(needed) else None,
                           "bodies_without_overturn": [r.body_id for r in rows if r.cor is None]})
        return {"sequence": self.sequence, "model": self.model, "restitution": self.restitution,
                "margin": self.margin, "power": self.power, "records": self.records,
                "repetitions": self.repetitions, "angles": angles, "bodies": [b.to_json() for b in self.bodies]}


def played_motion(sequence: Sequence, run: PlannedRun) -> PlayedMotion:
    """The run's drive (`Sequence.prepare`, raising its `SequenceError`) as the models' ground motion."""
    drive = sequence.prepare(run)
    acc = drive.accelerations
    return PlayedMotion(name=sequence.records[run.record_index].label(), dt=1.0 / drive.rate,
                        acc_h=np.ascontiguousarray(acc[:, 0] / G), acc_v=np.ascontiguousarray(acc[:, 2] / G))


def plan_sequence(sequence: Sequence, *, margin: float = MARGIN, power: float = POWER, model: str = "rocking",
                  restitution: float | str = 0.0) -> SequencePlan:
    """The expected overturns per body and angle and the runs an equivalence verdict needs (module docstring).
    ``margin`` [fraction] and ``power`` in (0, 1). Raises `SequenceError` for a record or drive the sequence cannot
    play, `analysis.AnalysisInputError` for a bad model or impact rule, ValueError for a bad margin or power."""
    if not 0.0 < margin < 1.0:
        raise ValueError(f"margin {margin!r}: expected a fraction in (0, 1) (0.05 = 5 points)")
    if not 0.0 < power < 1.0:
        raise ValueError(f"power {power!r}: expected a probability in (0, 1)")
    bodies = [placed.body for placed in sequence.bodies]
    first_pass = [run for run in sequence.plan() if run.repetition == 0]
    per_pass = len(sequence.records)
    runs = per_pass * sequence.repetitions
    needed_cache: dict[float, int | None] = {}
    rows: list[BodyPlan] = []
    for a, angle_deg in enumerate(sequence.angles_deg):
        problem = sequence.standing_problem(a)
        if problem:
            raise problem
        motions = [played_motion(sequence, run) for run in first_pass if run.angle_index == a]
        result = study(bodies, motions, [math.radians(angle_deg)],
                       model,  # type: ignore[arg-type]  # a str: study refuses a bad one
                       signs=(1,), restitution=restitution)
        for j, placed in enumerate(sequence.bodies):
            outcome = result.direction[result.body == j]
            overturned = int(np.count_nonzero(outcome)) * sequence.repetitions
            low = int(np.count_nonzero(outcome == 1)) * sequence.repetitions
            rate = low / overturned if overturned else None
            n = runs_needed = repetitions = None
            if rate is not None:
                key = round(rate, 4)
                if key not in needed_cache:
                    needed_cache[key] = cases_for_power(key, margin=margin, power=power)
                n = needed_cache[key]
                if n is not None:
                    runs_needed = math.ceil(n * runs / overturned)
                    repetitions = math.ceil(runs_needed / per_pass)
            rows.append(BodyPlan(angle_deg, placed.body_id, placed.name, runs, overturned, low, rate, n,
                                 runs_needed, repetitions))
    return SequencePlan(sequence.name, model, str(restitution), margin, power, per_pass, sequence.repetitions, rows)
