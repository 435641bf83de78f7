"""``rig analyze --restitution fit``: each body's coefficient of restitution identified from the session's measured
body tilts, for the models' impacts.

Every completed run's ``tilt/<body_id>`` samples (the body's rocking angle from its tilt sensor, 200 Hz on the
emulated table) give the ratio of angular velocities across each clean impact (`analysis.restitution`) of its
**free rocking**: only impacts while the measured plate is still (its fall-line acceleration within
:data:`QUIET_G` of rest from :data:`QUIET_MARGIN` s before to after the impact's fit windows) — the decays after
the record, while the drive holds the plate at its tilt for ``settle_s`` (a longer ``settle_s`` records longer
decays; a short "tap" run adds decays on purpose). During shaking the plate's acceleration changes within the
fits' 40 ms windows (a strong record by tenths of a g), which the quadratics cannot follow: ratios read there
scatter by ±20 % on the emulator. A body's restitution is the median over its free impacts in the session, with
a 95 % interval. A body with fewer than :data:`MIN_IMPACTS` clean impacts (it hardly rocked) gets
Housner's 1 − 1.5 sin²α, said so in the result; a session without any tilt samples (recorded over CANopen, or
before the tilt sensors) cannot be fitted and is refused.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis import AnalysisInputError, Body
from analysis.restitution import WINDOW, Impact, fit_restitution, impact_ratios

from .transform import TransformError, measured_inputs

MIN_IMPACTS = 3
"""Clean free impacts a body needs for its fitted restitution to be used."""

QUIET_G = 0.02
"""Largest |fall-line plate acceleration| [g] of a still plate (the accelerometers' noise is about 0.002 g)."""

QUIET_MARGIN = 0.1
"""Seconds of still plate needed beyond an impact's fit windows on each side."""


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
        tilts = {int(body_id): tilt for body_id, tilt in run.get("tilt", {}).items() if len(tilt) > 1}
        samples += sum(len(tilt) for tilt in tilts.values())
        if not tilts:
            continue
        still = _still_plate(run)
        for body_id, tilt in tilts.items():
            free = [impact for impact in impact_ratios(tilt[:, 0], tilt[:, 1]) if still(impact)]
            impacts.setdefault(body_id, []).extend(free)
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


def _still_plate(run: dict[str, Any]) -> Any:
    """A test of one run: was the measured plate still around this impact (module docstring)? Never, for a run
    without usable accelerometer samples."""
    try:
        inp = measured_inputs(run["accel"], math.radians(float(run["angle_deg"])))
    except TransformError:
        return lambda impact: False
    moving = np.abs(inp.acc_h) > QUIET_G
    reach = WINDOW + QUIET_MARGIN

    def still(impact: Impact) -> bool:
        lo = math.floor((impact.t - reach - inp.t0) / inp.dt)
        hi = math.ceil((impact.t + reach - inp.t0) / inp.dt)
        return lo >= 0 and hi < moving.size and not moving[lo:hi + 1].any()

    return still
