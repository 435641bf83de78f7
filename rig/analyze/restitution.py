"""``rig analyze --restitution fit``: each body's coefficient of restitution identified from the session's measured
body tilts, for the models' impacts.

Every completed run's ``tilt/<body_id>`` samples (the body's rocking angle from its tilt sensor, 200 Hz on the
emulated table) give the ratio of angular velocities across each clean impact (`analysis.restitution`): during
the record and in the free rocking after it (the drive holds the plate still for ``settle_s`` before tilting
back; a short "tap" run adds decays on purpose). A body's restitution is the median over all its impacts in the
session, with a 95 % interval. A body with fewer than :data:`MIN_IMPACTS` clean impacts (it hardly rocked) gets
Housner's 1 − 1.5 sin²α, said so in the result; a session without any tilt samples (recorded over CANopen, or
before the tilt sensors) cannot be fitted and is refused.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from analysis import AnalysisInputError, Body
from analysis.restitution import fit_restitution, impact_ratios

MIN_IMPACTS = 3
"""Clean impacts a body needs for its fitted restitution to be used."""


@dataclass(frozen=True)
class BodyRestitution:
    """The restitution the models use for one body: ``value``; ``source`` ``"fit"`` (the median of ``impacts``
    ratios, 95 % interval [``low``, ``high``]) or ``"housner"`` (too few impacts: ``impacts`` found)."""

    body_id: int
    value: float
    source: str
    impacts: int
    low: float
    high: float

    def to_json(self) -> dict[str, Any]:
        return {"body_id": self.body_id, "value": self.value, "source": self.source, "impacts": self.impacts,
                "low": None if math.isnan(self.low) else self.low, "high": None if math.isnan(self.high) else self.high}

    def label(self) -> str:
        """``0.934 [0.928–0.940] from 17 impacts`` or ``0.942 (Housner's: 1 impact measured)``."""
        if self.source == "fit":
            return f"{self.value:.3f} [{self.low:.3f}–{self.high:.3f}] from {self.impacts} impacts"
        return f"{self.value:.3f} (Housner's: {self.impacts} impact{'' if self.impacts == 1 else 's'} measured)"


def fitted_restitution(runs: Iterable[dict[str, Any]]) -> dict[int, BodyRestitution]:
    """{body_id: BodyRestitution} from the completed runs among ``runs`` (as `rig.session.read_session` gives
    them, with data; module docstring). Raises `AnalysisInputError` when no run has any tilt sample, or a body's
    median ratio is above 1 (no impact gains energy: the measurement is wrong)."""
    impacts: dict[int, list[Any]] = {}
    rows: dict[int, dict[str, Any]] = {}
    samples = 0
    for run in runs:
        if str(run["status"]) != "completed":
            continue
        for row in run["bodies"]:
            rows.setdefault(int(row["body_id"]), row)
        for body_id, tilt in run.get("tilt", {}).items():
            samples += len(tilt)
            if len(tilt) > 1:
                impacts.setdefault(int(body_id), []).extend(impact_ratios(tilt[:, 0], tilt[:, 1]))
    if samples == 0:
        raise AnalysisInputError("restitution 'fit': the session's completed runs hold no body tilt samples "
                                 "(tilt/<body_id>: the table sends none over CANopen, and files written before the "
                                 "tilt sensors have none); use 'housner' or a number")
    out = {}
    for body_id, row in sorted(rows.items()):
        found = impacts.get(body_id, [])
        fit = fit_restitution(found)
        if fit.impacts >= MIN_IMPACTS:
            if fit.value > 1.0:
                raise AnalysisInputError(f"restitution 'fit': body {body_id}'s impacts give {fit.value:.3f} "
                                         f"(median of {fit.impacts}), above 1; use 'housner' or a number")
            out[body_id] = BodyRestitution(body_id, fit.value, "fit", fit.impacts, fit.low, fit.high)
        else:
            try:
                housner = Body(b=float(row["b"]), h=float(row["h"])).housner_restitution()
            except AnalysisInputError:
                continue  # not a body the models can run (the analysis lists it as not analysed)
            out[body_id] = BodyRestitution(body_id, housner, "housner", fit.impacts, math.nan, math.nan)
    return out
