"""The report's sensor sheets: every accelerometer's and every body's tilt sensor's calibration sheet as the
session stored it (the rig configuration's ``[sensors]``, ``analysis.table.sensors``), with the runs in which it
clipped."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

from analysis.body import G

from .html import num, table


def sensors_table(rig_config: Mapping[str, Any], runs: Sequence[Mapping[str, Any]]) -> str:
    """The sheets of ``rig_config`` (the session's stored configuration) as two tables, accelerometers and tilt
    sensors ("" without sheets); a sensor's clipped samples summed over ``runs`` (their ``clipped`` and
    ``tilt_clipped`` attributes, JSON)."""
    stored = rig_config.get("sensors")
    if not isinstance(stored, Mapping):
        return ""
    sheets = {name: sheet for name, sheet in stored.items() if name != "tilt" and isinstance(sheet, Mapping)}
    tilts = stored.get("tilt")
    tilts = {body: sheet for body, sheet in tilts.items() if isinstance(sheet, Mapping)} if isinstance(
        tilts, Mapping) else {}
    policy = stored.get("overdue", "warn")
    return _accelerometers(sheets, _clipped(runs, "clipped"), policy) + _tilts(tilts, _clipped(runs, "tilt_clipped"),
                                                                               policy)


def _clipped(runs: Sequence[Mapping[str, Any]], attribute: str) -> dict[str, int]:
    """{sensor: clipped samples} summed over ``runs``' JSON ``attribute``."""
    clipped: dict[str, int] = {}
    for run in runs:
        text = (run.get("attrs") or {}).get(attribute)
        for name, samples in (json.loads(text) if isinstance(text, str) and text else {}).items():
            clipped[name] = clipped.get(name, 0) + int(samples)
    return clipped


def _tilts(sheets: Mapping[str, Mapping[str, Any]], clipped: Mapping[str, int], policy: str) -> str:
    """The tilt sensors' sheets (range stored in rad) as a table, "" without any."""
    if not sheets:
        return ""
    rows = [[body, sheet.get("model"), sheet.get("serial"),
             f"±{num(sheet.get('range'), '.4g')} (±{num(sheet.get('range'), '.3g', 180 / math.pi)}°)",
             sheet.get("calibrated"), sheet.get("due"), clipped.get(body, "–")]
            for body, sheet in sheets.items()]
    return table(["body", "model", "serial", "range [rad]", "calibrated", "due", "clipped samples"], rows, left=3,
                 caption=(f"Tilt sensors' calibration sheets (overdue sensors: {policy}); each body's rocking angle "
                          "relative to the plate; clipped: samples at or beyond the full scale in all runs"))


def _accelerometers(sheets: Mapping[str, Mapping[str, Any]], clipped: Mapping[str, int], policy: str) -> str:
    """The accelerometers' sheets as a table, "" without any."""
    if not sheets:
        return ""
    rows = [[name, sheet.get("model"), sheet.get("serial"),
             f"{num(sheet.get('sensitivity'), 'g')} {sheet.get('sensitivity_unit', '')}",
             f"±{num(sheet.get('range'), '.4g')} (±{num(sheet.get('range'), '.3g', 1 / G)} g)",
             sheet.get("calibrated"), sheet.get("due"),
             ", ".join(num(c, ".3g") for c in sheet.get("place_m", [])), ", ".join(sheet.get("axes", [])),
             clipped.get(name, "–")]
            for name, sheet in sheets.items()]
    return table(["sensor", "model", "serial", "sensitivity", "range [m/s²]", "calibrated", "due",
                  "place x, y, z [m]", "axes", "clipped samples"], rows, left=3, caption=(
        f"Accelerometers' calibration sheets (overdue sensors: {policy}); place in the plate frame, axes: the "
        "plate axis of each of the sensor's axes; clipped: samples at or beyond the full scale in all runs"))
