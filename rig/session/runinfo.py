"""`RunInfo`: the attributes of one run group, as the writer and its callers see them."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class RunInfo:
    """One run group. ``angle_deg`` in degrees; ``started``/``ended`` ISO 8601 (``ended`` ``""`` while running)."""

    name: str
    plan_index: int
    attempt: int
    status: str
    record: str
    angle_deg: float
    scale_factor: float
    started: str
    ended: str


def text(value: Any) -> str:
    """An attribute value as str (fixed-length strings come back from h5py as bytes)."""
    if isinstance(value, bytes | np.bytes_):
        return bytes(value).decode("utf-8", "replace")
    return str(value)


def run_info(name: str, attrs: Mapping[str, Any]) -> RunInfo:
    """`RunInfo` from a run group's attributes (missing ones read as empty / -1)."""
    return RunInfo(name=name, plan_index=int(attrs.get("plan_index", -1)), attempt=int(attrs.get("attempt", 0)),
                   status=text(attrs.get("status", "")), record=text(attrs.get("record", "")),
                   angle_deg=float(attrs.get("angle_deg", np.nan)),
                   scale_factor=float(attrs.get("scale_factor", np.nan)),
                   started=text(attrs.get("started", "")), ended=text(attrs.get("ended", "")))
