"""The report's sensor sheets: every accelerometer's calibration sheet as the session stored it (the rig
configuration's ``[sensors]``, ``analysis.table.sensors``), with the runs in which it clipped."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

from analysis.body import G

from .html import num, table


def sensors_table(rig_config: Mapping[str, Any], runs: Sequence[Mapping[str, Any]]) -> str:
    """The sheets of ``rig_config`` (the session's stored configuration) as one table, "" without sheets; a
    sensor's clipped samples summed over ``runs`` (their ``clipped`` attribute, JSON)."""
    stored = rig_config.get("sensors")
    if not isinstance(stored, Mapping):
        return ""
    sheets = {name: sheet for name, sheet in stored.items() if isinstance(sheet, Mapping)}
    if not sheets:
        return ""
    clipped: dict[str, int] = {}
    for run in runs:
        text = (run.get("attrs") or {}).get("clipped")
        for name, samples in (json.loads(text) if isinstance(text, str) and text else {}).items():
            clipped[name] = clipped.get(name, 0) + int(samples)
    rows = [[name, sheet.get("model"), sheet.get("serial"),
             f"{num(sheet.get('sensitivity'), 'g')} {sheet.get('sensitivity_unit', '')}",
             f"±{num(sheet.get('range'), '.4g')} (±{num(sheet.get('range'), '.3g', 1 / G)} g)",
             sheet.get("calibrated"), sheet.get("due"),
             ", ".join(num(c, ".3g") for c in sheet.get("place_m", [])), ", ".join(sheet.get("axes", [])),
             clipped.get(name, "–")]
            for name, sheet in sheets.items()]
    policy = stored.get("overdue", "warn")
    return table(["sensor", "model", "serial", "sensitivity", "range [m/s²]", "calibrated", "due",
                  "place x, y, z [m]", "axes", "clipped samples"], rows, left=3, caption=(
        f"Accelerometers' calibration sheets (overdue sensors: {policy}); place in the plate frame, axes: the "
        "plate axis of each of the sensor's axes; clipped: samples at or beyond the full scale in all runs"))
