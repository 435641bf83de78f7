"""The ``analysis`` groups of a session file: written here, never touching its raw data, and read back here.

Layout (schema ``shaketable-rig/analysis/1``):

* ``/runs/<NNNN>/analysis/`` per analysed run: attributes ``schema``, ``software_version``, ``created`` (ISO 8601
  UTC), ``transform`` (`rig.analyze.transform.DESCRIPTION`), ``models`` and ``sensors`` (JSON lists), ``solver``,
  ``restitution`` (the models' impact rule, text), ``fitted_restitution`` (JSON list, with ``fit``: per body
  ``body_id``, ``value``, ``source`` ``fit``/``housner``, ``impacts``, ``low``, ``high``; empty otherwise),
  ``angle_deg``, ``dt`` [s], ``t0`` [s], ``duration`` [s], ``resampled``, ``gaps``, ``notes`` and
  ``skipped_bodies`` (JSON); dataset ``predictions`` (`PREDICTION`): body_id, model, direction (+1 low side, −1
  high side, 0 none), t_overturn [s, run clock, NaN if none], theta_max [rad], observed (direction, 0 if none),
  then t_observed [s, NaN if none] and status (the model's end state).
* ``/analysis/``: the same provenance attributes plus ``runs`` and ``skipped_runs`` (JSON), ``max_difference``
  (JSON {model: value or null}) and ``max_difference_<model>`` (float, NaN if undefined), ``agreement`` (JSON),
  ``margin`` (the equivalence margin of the verdicts, fraction), ``cor_definition`` (text); dataset ``fig13``
  (`rig.analyze.fig13.FIG13_DTYPE`).

How: the writer's own locks (`rig.session.locks.open_locked`: refused at once while a `SessionLog` holds the
file) and one crash-atomic transaction (`rig.session.atomic.SessionFile.transaction`: the file is the old one or
the new one, also after a ``kill -9``). Every old ``analysis`` group is deleted and the new ones written in the
same transaction, so re-running replaces them. A file still marked open for writing (a run being recorded, or
a writer that died: resume it first) is refused.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from rig import __version__
from rig.session import SessionError, crashed_message, open_session
from rig.session.atomic import SessionFile
from rig.session.check import hdf5_error
from rig.session.locks import open_locked
from rig.session.reader import attributes, child, records
from rig.session.schema import iso_now

from . import fig13
from .restitution import BodyRestitution
from .results import SessionAnalysis
from .transform import DESCRIPTION

SCHEMA = "shaketable-rig/analysis/1"
GROUP = "analysis"

#: Compound layout of ``/runs/<NNNN>/analysis/predictions``.
PREDICTION = np.dtype([("body_id", "<i4"), ("model", "S16"), ("direction", "i1"), ("t_overturn", "<f8"),
                       ("theta_max", "<f8"), ("observed", "i1"), ("t_observed", "<f8"), ("status", "S16")])


class SessionBusyError(SessionError):
    """The session file is being written (or its writer died): the analysis cannot be stored now."""


@contextlib.contextmanager
def locked(path: Path) -> Iterator[SessionFile]:
    """The session file under the writer's locks, checked not to be marked open for writing."""
    try:
        fd = open_locked(path)
    except SessionError as exc:
        if "no such" in str(exc):
            raise
        raise SessionBusyError(f"{path}: a session log is writing this file (rig run, or a program holding it "
                               f"open for writing); analyse it once the session has ended ({exc})") from None
    file = SessionFile(path, fd)
    try:
        if file.superblock().flags:  # we hold the writer's lock, so no live writer: it was killed
            raise SessionBusyError(crashed_message(path))
        yield file
    finally:
        file.close()


def _provenance(analysis: SessionAnalysis, created: str) -> dict[str, str]:
    return {"schema": SCHEMA, "software_version": __version__, "created": created, "transform": DESCRIPTION,
            "models": json.dumps(list(analysis.models)), "solver": analysis.solver,
            "restitution": analysis.restitution,
            "fitted_restitution": json.dumps([b.to_json() for b in analysis.fitted_restitution.values()])}


def prediction_rows(analysis: SessionAnalysis, run: str) -> np.ndarray:
    """The `PREDICTION` rows of one analysed run."""
    ra = next(r for r in analysis.runs if r.run == run)
    out = np.zeros(len(ra.predictions), dtype=PREDICTION)
    for i, p in enumerate(ra.predictions):
        out[i] = (p.body_id, p.model.encode(), p.direction, p.t_overturn, p.theta_max, p.observed, p.t_observed,
                  p.status.encode())
    return out


def write(file: SessionFile, analysis: SessionAnalysis) -> None:
    """Replace every ``analysis`` group of the file with ``analysis`` (module docstring), in one transaction."""
    created = iso_now()
    with file.transaction() as h5:
        runs = h5.get("runs")
        names = sorted(runs) if runs is not None else []
        for name in names:
            if GROUP in runs[name]:
                del runs[name][GROUP]
        if GROUP in h5:
            del h5[GROUP]
        for ra in analysis.runs:
            group = runs[ra.run].create_group(GROUP)
            _write_run(group, analysis, ra.run, created)
        _write_root(h5.create_group(GROUP), analysis, created)


def _write_run(group: h5py.Group, analysis: SessionAnalysis, run: str, created: str) -> None:
    ra = next(r for r in analysis.runs if r.run == run)
    inp = ra.input
    group.attrs.update(_provenance(analysis, created))
    group.attrs.update({
        "angle_deg": ra.angle_deg, "sensors": json.dumps(list(inp.sensors)), "dt": inp.dt, "t0": inp.t0,
        "duration": inp.duration, "resampled": inp.resampled, "gaps": inp.gaps, "notes": json.dumps(list(inp.notes)),
        "skipped_bodies": json.dumps([{"body_id": b, "reason": r} for b, r in ra.skipped_bodies]),
        "clipped": json.dumps(ra.clipped),
    })
    group.create_dataset("predictions", data=prediction_rows(analysis, run))


def _write_root(group: h5py.Group, analysis: SessionAnalysis, created: str) -> None:
    group.attrs.update(_provenance(analysis, created))
    clean = {m: (None if v is None or math.isnan(v) else v) for m, v in analysis.max_difference.items()}
    group.attrs.update({
        "runs": json.dumps([r.run for r in analysis.runs]),
        "skipped_runs": json.dumps([s.to_json() for s in analysis.skipped]),
        "max_difference": json.dumps(clean),
        "margin": float(analysis.margin),
        "agreement": json.dumps({m: a.to_json() for m, a in analysis.agreement.items()}),
        "cor_definition": (fig13.__doc__ or "").strip(),
    })
    for model, value in clean.items():
        group.attrs[f"max_difference_{model}"] = math.nan if value is None else float(value)
    group.create_dataset("fig13", data=fig13.to_array(analysis.fig13))


def read_results(path: str | os.PathLike[str]) -> tuple[list[dict[str, Any]] | None, dict[str, Any]]:
    """The session's ``/analysis`` group: its ``fig13`` rows (dicts of plain values; None when the session was not
    analysed) and its attributes (module docstring; empty when not analysed)."""
    with open_session(path) as h5:
        try:
            group = child(h5, GROUP)
            if not isinstance(group, h5py.Group):
                return None, {}
            rows = records(group["fig13"]) if isinstance(child(group, "fig13"), h5py.Dataset) else None
            return rows, attributes(group)
        except (OSError, RuntimeError, KeyError, ValueError) as exc:
            raise hdf5_error(path, exc, f"/{GROUP}") from None


def fitted_restitution(attrs: Mapping[str, Any]) -> list[BodyRestitution]:
    """The per-body restitution of ``rig analyze --restitution fit`` from the ``/analysis`` attributes
    (`read_results`); empty for any other impact rule or an older analysis."""
    try:
        rows = json.loads(attrs.get("fitted_restitution") or "[]")
    except ValueError:
        return []
    return [BodyRestitution(int(r["body_id"]), float(r["value"]), str(r["source"]), int(r["impacts"]),
                            math.nan if r.get("low") is None else float(r["low"]),
                            math.nan if r.get("high") is None else float(r["high"])) for r in rows]


def run_predictions(run: Mapping[str, Any]) -> list[dict[str, Any]] | None:
    """A run's ``analysis/predictions`` rows from a run as `rig.session.read_session` gives it, None when the run
    was not analysed."""
    analysis = run.get("analysis")
    return analysis.get("predictions") if isinstance(analysis, Mapping) else None
