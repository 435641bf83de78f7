"""The identification and the iterations in the session file: the ``/compensation`` group (additive; the runs and
their datasets are the session schema's own).

Layout (schema ``shaketable-rig/compensation/1``), written once the session log is closed, in one crash-atomic
transaction under the writer's locks (``rig.analyze.store.locked``), replacing an earlier ``/compensation``:

* attributes ``schema``, ``record``, ``angle_deg``, ``identification_run`` (run name), ``runs`` (JSON list of the
  iterations' run names, iteration 0 first), ``best`` (iteration index), ``converged``, ``stopped`` (text),
  ``drive_file`` (path of the compensated drive, "" if none), ``band_hz`` [low, high];
* ``response``: compound (f [Hz], then per axis surge/lateral/heave: ``h_re``, ``h_im`` (H1 from commanded to
  measured base-frame acceleration), ``coherence``);
* ``iterations``: compound (index, run (text), rms_error_pct, peak_error_pct, gain, seconds);
* ``target`` (n,) and ``achieved`` (iterations, n): fall-line acceleration [m/s²] over the record's motion, and
  ``t`` (n,) [s, run clock].
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from analysis.table.model import AXES

from .identify import FrequencyResponse
from .iteration import Compensation

SCHEMA = "shaketable-rig/compensation/1"
GROUP = "compensation"

ITERATION = np.dtype([("index", "<i4"), ("run", "S8"), ("rms_error_pct", "<f8"), ("peak_error_pct", "<f8"),
                      ("gain", "<f8"), ("seconds", "<f8")])
RESPONSE = np.dtype([("f", "<f8"), *[(f"{axis}_{part}", "<f8") for axis in AXES
                                       for part in ("h_re", "h_im", "coherence")]])


def response_rows(response: FrequencyResponse) -> np.ndarray:
    """The `RESPONSE` rows of a frequency response."""
    rows = np.zeros(len(response.f), RESPONSE)
    rows["f"] = response.f
    for k, axis in enumerate(AXES):
        rows[f"{axis}_h_re"] = response.h[:, k].real
        rows[f"{axis}_h_im"] = response.h[:, k].imag
        rows[f"{axis}_coherence"] = response.coherence[:, k]
    return rows


def response_from_rows(rows: np.ndarray, band: tuple[float, float]) -> FrequencyResponse:
    """A `FrequencyResponse` back from `RESPONSE` rows."""
    h = np.column_stack([rows[f"{a}_h_re"] + 1j * rows[f"{a}_h_im"] for a in AXES])
    coherence = np.column_stack([rows[f"{a}_coherence"] for a in AXES])
    return FrequencyResponse(f=np.array(rows["f"]), h=h, coherence=coherence, band=band)


def write(path: Path, *, record: str, angle_deg: float, identification_run: str, iteration_runs: list[str],
          response: FrequencyResponse, result: Compensation, t: np.ndarray, drive_file: str) -> None:
    """Replace the session's ``/compensation`` group (module docstring)."""
    from rig.analyze.store import locked

    motion = result.motion
    with locked(Path(path)) as file, file.transaction() as h5:
        if GROUP in h5:
            del h5[GROUP]
        group = h5.create_group(GROUP)
        group.attrs.update({
            "schema": SCHEMA, "record": record, "angle_deg": float(angle_deg),
            "identification_run": identification_run, "runs": json.dumps(iteration_runs), "best": result.best,
            "converged": bool(result.converged), "stopped": result.stopped, "drive_file": drive_file,
            "band_hz": np.array(response.band, dtype=float)})
        group.create_dataset("response", data=response_rows(response))
        rows = np.zeros(len(result.iterations), ITERATION)
        for k, it in enumerate(result.iterations):
            rows[k] = (it.index, iteration_runs[k].encode() if k < len(iteration_runs) else b"",
                       it.rms_error_pct, it.peak_error_pct, it.gain, it.seconds)
        group.create_dataset("iterations", data=rows)
        group.create_dataset("t", data=np.asarray(t)[motion])
        group.create_dataset("target", data=result.target[motion])
        group.create_dataset("achieved", data=np.stack([a[motion] for a in result.achieved]))


def read(path: str | os.PathLike[str]) -> dict[str, Any] | None:
    """The session's ``/compensation`` group (module docstring), None when it has none: ``attrs`` (plain values)
    and the arrays ``response``, ``iterations`` (compound rows), ``t``, ``target`` and ``achieved``."""
    from rig.session import open_session
    from rig.session.reader import attributes

    with open_session(path) as h5:
        group = h5.get(GROUP)
        if group is None:
            return None
        out: dict[str, Any] = {"attrs": attributes(group)}
        out.update({key: group[key][()] for key in ("response", "iterations", "t", "target", "achieved")})
        return out


def summary(group: object) -> dict[str, object]:
    """The group's attributes and iterations as plain JSON values (for reports and ``--json``)."""
    from rig.session.reader import plain

    attrs = {key: plain(group.attrs[key]) for key in group.attrs}  # type: ignore[attr-defined]
    rows = group["iterations"][()]  # type: ignore[index]
    attrs["iterations"] = [{"index": int(r["index"]), "run": r["run"].decode(),
                            "rms_error_pct": float(r["rms_error_pct"]), "peak_error_pct": float(r["peak_error_pct"]),
                            "gain": float(r["gain"]), "seconds": float(r["seconds"])} for r in rows]
    if isinstance(attrs.get("runs"), str):
        attrs["runs"] = json.loads(attrs["runs"])
    attrs["angle_deg"] = float(attrs.get("angle_deg", math.nan))
    return attrs
