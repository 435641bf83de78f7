"""Reading what a report shows: a session file's runs one at a time (a campaign holds hundreds of MB of
samples), the ``analysis`` results ``rig analyze`` adds to it, and which kind a file is. Every file is opened read-only
the way session readers must (``swmr=True``, no HDF5 file lock); nothing is ever written to an input.

Analysis results in a session file (written by ``rig analyze``):

* ``/runs/<NNNN>/analysis/predictions``: compound (body_id i4, model S16, direction i1, t_overturn f8 — NaN if
  none, theta_max f8, observed i1);
* ``/analysis/fig13``: compound (angle_deg f8, body_id i4 — 0 the average over the bodies, model S16, runs i4,
  overturned_analysis i4, towards_low_analysis i4, cor_analysis f8, overturned_experiment i4,
  towards_low_experiment i4, cor_experiment f8, difference f8), attributes ``max_difference_<model>``.

A study file is read by its writer's module, ``rig.study_file`` (``read_study``); here only its kind is told.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from rig.session import SCHEMA as SESSION_SCHEMA
from rig.session import open_session, read_session
from rig.session.reader import plain
from rig.study_file import SCHEMA as STUDY_SCHEMA


class ReportError(ValueError):
    """The input cannot be reported on (unknown kind, unreadable, missing parts); the message says which."""


def open_h5(path: str | os.PathLike[str]) -> h5py.File:
    """Open any of our HDF5 files for reading: as a SWMR reader first (a session file may be being written),
    else plainly; no HDF5 file lock either way."""
    path = Path(path)
    if not path.is_file():
        raise ReportError(f"{path}: no such file")
    try:
        return h5py.File(path, "r", swmr=True, locking=False)
    except OSError:
        try:
            return h5py.File(path, "r", locking=False)
        except OSError as exc:
            raise ReportError(f"{path}: not an HDF5 file ({exc})") from None


def file_kind(path: str | os.PathLike[str]) -> str:
    """``"session"`` or ``"study"``, by the root ``schema`` attribute; `ReportError` otherwise."""
    with open_h5(path) as h5:
        schema = plain(h5.attrs.get("schema"))
    if schema == SESSION_SCHEMA:
        return "session"
    if schema == STUDY_SCHEMA:
        return "study"
    raise ReportError(f"{path}: schema attribute is {schema!r}; expected {SESSION_SCHEMA!r} (a session file) or "
                      f"{STUDY_SCHEMA!r} (a study file)")


def records(ds: h5py.Dataset) -> list[dict[str, Any]]:
    """A compound dataset as dicts of plain values (bytes → str)."""
    data = ds[()]
    names = data.dtype.names or ()
    return [{name: plain(row[name]) for name in names} for row in np.atleast_1d(data)]


def attrs(obj: h5py.HLObject) -> dict[str, Any]:
    """Attributes as plain values."""
    return {key: plain(obj.attrs[key]) for key in obj.attrs}


# -- sessions -------------------------------------------------------------------------------------------------


@dataclass
class RunData:
    """One run as the report needs it (times in s on the run's clock, SI units)."""

    name: str
    record: str
    scale_factor: float | None
    angle_deg: float
    status: str
    attrs: dict[str, Any]
    commanded: np.ndarray
    """(N, 7): t, surge, sway, heave [m], roll, pitch, yaw [rad]."""
    accel: dict[str, np.ndarray]
    """sensor → (M, 4): t, ax, ay, az [m/s², plate-frame specific force]."""
    bodies: list[dict[str, Any]] = field(default_factory=list)
    detections: list[dict[str, Any]] = field(default_factory=list)
    faults: list[dict[str, Any]] = field(default_factory=list)
    events: list[dict[str, Any]] = field(default_factory=list)
    predictions: list[dict[str, Any]] | None = None
    """``analysis/predictions`` rows, None when the run was not analysed."""


@dataclass
class SessionData:
    """A session's header: the parsed root attributes and the runs' summaries (no samples)."""

    path: Path
    software_version: str | None
    created: str | None
    rig_config: dict[str, Any]
    sequence: dict[str, Any]
    runs: list[dict[str, Any]]
    fig13: list[dict[str, Any]] | None
    """``/analysis/fig13`` rows, None when the session was not analysed."""
    analysis_attrs: dict[str, Any]


def read_header(path: str | os.PathLike[str]) -> SessionData:
    """The session's root attributes, its runs' attributes and the Fig. 13 table (if analysed)."""
    session = read_session(path, data=False)
    fig13, analysis_attrs = None, {}
    with open_session(path) as h5:
        group = h5.get("analysis")
        if isinstance(group, h5py.Group):
            analysis_attrs = attrs(group)
            if isinstance(group.get("fig13"), h5py.Dataset):
                fig13 = records(group["fig13"])
    return SessionData(path=Path(path), software_version=session.get("software_version"),
                       created=session.get("created"), rig_config=session.get("rig_config") or {},
                       sequence=session.get("sequence") or {}, runs=session["runs"], fig13=fig13,
                       analysis_attrs=analysis_attrs)


def _run(group: h5py.Group, name: str) -> RunData:
    a = attrs(group)
    scale = a.get("scale_factor")
    return RunData(
        name=name, record=str(a.get("record", "")),
        scale_factor=None if scale is None or not np.isfinite(scale) else float(scale),
        angle_deg=float(a.get("angle_deg", 0.0)), status=str(a.get("status", "")), attrs=a,
        commanded=group["commanded"][()] if "commanded" in group else np.zeros((0, 7)),
        accel={s: ds[()] for s, ds in group["accel"].items()} if "accel" in group else {},
        **{key: records(group[key]) if key in group else [] for key in ("bodies", "detections", "faults",
                                                                         "events")},
        predictions=(records(group["analysis/predictions"])
                     if isinstance(group.get("analysis/predictions"), h5py.Dataset) else None),
    )


def iter_runs(path: str | os.PathLike[str]) -> Iterator[RunData]:
    """The session's runs in order, each read when it is asked for (one run's samples in memory at a time)."""
    with open_session(path) as h5:
        runs = h5.get("runs")
        for name in sorted(runs) if runs is not None else []:
            yield _run(runs[name], name)
