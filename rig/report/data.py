"""What a report shows, read through the modules that write it: a session file's header and runs one at a time
(`rig.session.reader`: a campaign holds hundreds of MB of samples), the ``analysis`` results of ``rig analyze``
(`rig.analyze.store`), and which kind a file is. A study file is read by its writer's module, ``rig.study_file``
(``read_study``); here only its kind is told. Nothing is ever written to an input.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from rig.analyze.store import read_results, run_predictions
from rig.session import SCHEMA as SESSION_SCHEMA
from rig.session import check, checksums, read_session
from rig.session.reader import iter_runs as session_runs
from rig.session.reader import plain
from rig.session.superblock import SIGNATURE
from rig.study_file import SCHEMA as STUDY_SCHEMA


class ReportError(ValueError):
    """The input cannot be reported on (unknown kind, unreadable, missing parts); the message says which."""


def _open_any(path: str | os.PathLike[str]) -> h5py.File:
    """Open any of our HDF5 files for reading, after the checks of `rig.session.check` and with HDF5's retries
    bounded: as a SWMR reader first (a session file may be being written), else plainly (a study file); no HDF5 file
    lock either way. `DamagedFileError` (a `SessionError`) for a damaged file."""
    path = Path(path)
    if not path.is_file():
        raise ReportError(f"{path}: no such file")
    with open(path, "rb") as f:
        head = f.read(len(SIGNATURE))
    if head != SIGNATURE and head.strip(b"\0"):  # some other file; one of zeros is a damaged one (check_hdf5)
        raise ReportError(f"{path}: not an HDF5 file (no HDF5 signature at byte 0); expected a session or study file")
    check.check_hdf5(path)
    try:
        return check.open_read(path, swmr=True)
    except OSError:
        try:
            return check.open_read(path, swmr=False)
        except OSError as exc:
            raise check.hdf5_error(path, exc) from None


def file_kind(path: str | os.PathLike[str]) -> str:
    """``"session"`` or ``"study"``, by the root ``schema`` attribute; `ReportError` otherwise, `DamagedFileError`
    for a file HDF5 cannot read."""
    with _open_any(path) as h5:
        try:
            schema = plain(h5.attrs.get("schema"))
        except (OSError, RuntimeError, KeyError, ValueError) as exc:
            raise check.hdf5_error(path, exc, "its root attributes") from None
    if schema == SESSION_SCHEMA:
        return "session"
    if schema == STUDY_SCHEMA:
        return "study"
    raise ReportError(f"{path}: schema attribute is {schema!r}; expected {SESSION_SCHEMA!r} (a session file) or "
                      f"{STUDY_SCHEMA!r} (a study file)")


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
    pose: np.ndarray = field(default_factory=lambda: np.zeros((0, 7)))
    """(K, 7): the measured pose from the controller's statuses, columns as ``commanded``."""
    following_error: np.ndarray = field(default_factory=lambda: np.zeros((0, 7)))
    """(J, 7): t [s], each leg's following error [m], legs 1…6, from the statuses that carry it."""
    bodies: list[dict[str, Any]] = field(default_factory=list)
    detections: list[dict[str, Any]] = field(default_factory=list)
    faults: list[dict[str, Any]] = field(default_factory=list)
    events: list[dict[str, Any]] = field(default_factory=list)
    predictions: list[dict[str, Any]] | None = None
    """``analysis/predictions`` rows, None when the run was not analysed."""
    checksum_notes: list[str] = field(default_factory=list)
    """What was not verified of the run's samples (`rig.session.checksums.notes`: a run written before checksums,
    rows after the last checksummed block); empty when all were."""


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
    fig13, analysis_attrs = read_results(path)
    return SessionData(path=Path(path), software_version=session.get("software_version"),
                       created=session.get("created"), rig_config=session.get("rig_config") or {},
                       sequence=session.get("sequence") or {}, runs=session["runs"], fig13=fig13,
                       analysis_attrs=analysis_attrs)


def _run(run: dict[str, Any]) -> RunData:
    scale = run.get("scale_factor")
    return RunData(
        name=run["name"], record=str(run.get("record") or ""),
        scale_factor=None if scale is None or not np.isfinite(scale) else float(scale),
        angle_deg=float(run.get("angle_deg") or 0.0), status=str(run.get("status") or ""), attrs=run["attrs"],
        commanded=run["commanded"], accel=run["accel"], pose=run.get("pose", np.zeros((0, 7))),
        following_error=run.get("following_error", np.zeros((0, 7))),
        **{key: run[key] for key in ("bodies", "detections", "faults", "events")},
        predictions=run_predictions(run), checksum_notes=checksums.notes(run.get("checksums")),
    )


def iter_runs(path: str | os.PathLike[str]) -> Iterator[RunData]:
    """The session's runs in order, each read when it is asked for (one run's samples in memory at a time)."""
    for run in session_runs(path):
        yield _run(run)
