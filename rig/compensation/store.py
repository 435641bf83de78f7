"""The identification and the iterations in the session file: the ``/compensation`` group (additive; the runs and
their datasets are the session schema's own).

Layout (schema ``shaketable-rig/compensation/3``), written once the session log is closed, in one crash-atomic
transaction under the writer's locks (``rig.analyze.store.locked``), replacing an earlier ``/compensation``:

* attributes ``schema``, ``record``, ``angle_deg``, ``identification_run`` (run name), ``runs`` (JSON list of the
  iterations' run names, iteration 0 first), ``best`` (iteration index), ``converged``, ``stopped`` (text),
  ``drive_file`` (path of the compensated drive, "" if none), ``band_hz`` [low, high], ``law`` (``mimo`` or
  ``diagonal``);
* ``response``: compound (f [Hz], then per axis surge/lateral/heave: ``h_re``, ``h_im`` (the direct term of H1 from
  commanded to measured base-frame acceleration), ``coherence`` (the multiple coherence of that output with the
  ``mimo`` law, the ordinary one with ``diagonal``), then ``condition`` (the response matrix's condition number per
  line; 0 with ``diagonal``)) — the response as last re-estimated;
* ``response_matrix`` (``mimo`` only): (lines, 3 outputs, 3 inputs) complex H1;
* ``iterations``: compound (index, run (text), level_db, rms_error_pct, peak_error_pct (fall line), per axis
  ``AXIS_rms_error_pct``, ``AXIS_peak_error_pct``, ``AXIS_trac``, then ``fall_line_trac``, ``psa_error_max_pct``,
  ``psa_error_mean_pct``, ``peak_to_limit``, gain, seconds, ``noise_floor_pct`` (the fall line's, NaN where not
  measured; since compensation/3); TRAC NaN where undefined);
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
from .iteration import Compensation, Iteration
from .mimo import MimoResponse

SCHEMA = "shaketable-rig/compensation/3"
GROUP = "compensation"

ITERATION = np.dtype([("index", "<i4"), ("run", "S8"), ("level_db", "<f8"), ("rms_error_pct", "<f8"),
                      ("peak_error_pct", "<f8"),
                      *[(f"{axis}_{part}", "<f8") for axis in AXES for part in ("rms_error_pct", "peak_error_pct",
                                                                                  "trac")],
                      ("fall_line_trac", "<f8"), ("psa_error_max_pct", "<f8"), ("psa_error_mean_pct", "<f8"),
                      ("peak_to_limit", "<f8"), ("gain", "<f8"), ("seconds", "<f8"), ("noise_floor_pct", "<f8")])
RESPONSE = np.dtype([("f", "<f8"), *[(f"{axis}_{part}", "<f8") for axis in AXES
                                       for part in ("h_re", "h_im", "coherence")], ("condition", "<f8")])


def response_rows(response: FrequencyResponse | MimoResponse) -> np.ndarray:
    """The `RESPONSE` rows of a per-axis or matrix response (its direct terms)."""
    rows = np.zeros(len(response.f), RESPONSE)
    rows["f"] = response.f
    direct = response.h if response.h.ndim == 2 else np.diagonal(response.h, axis1=1, axis2=2)
    for k, axis in enumerate(AXES):
        rows[f"{axis}_h_re"] = direct[:, k].real
        rows[f"{axis}_h_im"] = direct[:, k].imag
        rows[f"{axis}_coherence"] = response.coherence[:, k]
    if isinstance(response, MimoResponse):
        rows["condition"] = response.condition
    return rows


def iteration_row(it: Iteration, run: str) -> np.ndarray:
    """One `ITERATION` row."""
    row = np.zeros((), ITERATION)
    m = it.measures
    values = {"index": it.index, "run": run.encode(), "level_db": it.level_db, "rms_error_pct": it.rms_error_pct,
              "peak_error_pct": it.peak_error_pct, "fall_line_trac": m.fall_line["trac"],
              "psa_error_max_pct": m.psa_error_max_pct, "psa_error_mean_pct": m.psa_error_mean_pct,
              "peak_to_limit": m.peak_to_limit, "gain": it.gain, "seconds": it.seconds,
              "noise_floor_pct": m.noise_floor_pct}
    for axis in AXES:
        values.update({f"{axis}_{key}": value for key, value in m.axes[axis].items()})
    for key, value in values.items():
        row[key] = math.nan if value is None else value
    return row


def response_from_rows(rows: np.ndarray, band: tuple[float, float]) -> FrequencyResponse:
    """A `FrequencyResponse` back from `RESPONSE` rows."""
    h = np.column_stack([rows[f"{a}_h_re"] + 1j * rows[f"{a}_h_im"] for a in AXES])
    coherence = np.column_stack([rows[f"{a}_coherence"] for a in AXES])
    return FrequencyResponse(f=np.array(rows["f"]), h=h, coherence=coherence, band=band)


def write(path: Path, *, record: str, angle_deg: float, identification_run: str, iteration_runs: list[str],
          result: Compensation, t: np.ndarray, drive_file: str) -> None:
    """Replace the session's ``/compensation`` group (module docstring)."""
    from rig.analyze.store import locked

    motion, response = result.motion, result.response
    if not isinstance(response, FrequencyResponse | MimoResponse):
        raise ValueError("the compensation carries no response to store")
    with locked(Path(path)) as file, file.transaction() as h5:
        if GROUP in h5:
            del h5[GROUP]
        group = h5.create_group(GROUP)
        group.attrs.update({
            "schema": SCHEMA, "record": record, "angle_deg": float(angle_deg),
            "identification_run": identification_run, "runs": json.dumps(iteration_runs), "best": result.best,
            "converged": bool(result.converged), "stopped": result.stopped, "drive_file": drive_file,
            "band_hz": np.array(response.band, dtype=float), "law": result.law})
        group.create_dataset("response", data=response_rows(response))
        if isinstance(response, MimoResponse):
            group.create_dataset("response_matrix", data=response.h)
        rows = np.zeros(len(result.iterations), ITERATION)
        for k, it in enumerate(result.iterations):
            rows[k] = iteration_row(it, iteration_runs[k] if k < len(iteration_runs) else "")
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

