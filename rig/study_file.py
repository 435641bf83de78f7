"""A study saved as HDF5 (``rig study -o STUDY.h5``), schema ``shaketable-rig/study/1``.

Layout (any HDF5 tool reads it; h5py: ``h5py.File(path)["direction"][()]``):

* root attributes: ``schema``, ``software_version``, ``created`` (ISO 8601, UTC), ``model``,
  ``restitution`` (text: a number or ``housner``), ``friction`` (float), ``records`` (JSON list of names),
  ``bodies`` (JSON list of ``{"b", "h", "name"}`` and, where given, ``"b_cg"``, ``"h_cg"``, metres),
  ``angles_deg`` (float64 array, degrees), ``signs`` (int array: +1 the record as given, −1 negated),
  ``seconds`` (the study's wall time [s]),
  ``scenes``, ``where`` (``"local"`` or the Dask scheduler's address) and ``summary`` (JSON text of the
  ``rig study --json`` object);
* ``direction``: int8 (bodies, records, signs, angles): +1 overturned towards the low side, −1 towards
  the high side, 0 none;
* ``cor``: compound (body_index, angle_deg, overturned, desired, cor) per body and angle, cor NaN where
  nothing overturned; rows with body_index −1 are the body average (pooled counts, cor = mean of the
  bodies' defined rates, as Fig. 6);
* ``fits/gcor`` attributes c1 [rad], c2, c1_ci_low, c1_ci_high, c2_ci_low, c2_ci_high (NaN when c2 was
  held), rms, n, c2_fixed, eq12_error (fraction, body average), paper_c1, paper_c2, paper_eq12_error;
  ``fits/scor`` attributes k1 [rad], k2 [rad/m], k3 [rad], c2 and their ``_ci_low``/``_ci_high``, rms, n,
  c2_fixed, eq12_error, paper_k1, paper_k2, paper_k3, paper_c2, paper_eq12_error; a fit that failed has
  the attribute ``error`` (its message) instead of coefficients;
* ``estimators``: compound (body_index, equation "GCOR"/"SCOR", coefficients "paper"/"fitted",
  max_difference [pp], absolute_area [% · deg], error [%], paper_max_difference, paper_absolute_area,
  paper_error) — Table III; NaN where undefined or (paper_*) where the paper has no value.

`write_study` writes a temporary file beside the target and renames it into place (a reader sees the old
file or the complete new one); `read_study` checks the schema and returns a :class:`SavedStudy`.
"""

from __future__ import annotations

import json
import math
import os
import secrets
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from analysis.body import Body
from analysis.study import StudyResult, cor_counts
from rig import __version__
from rig.json_numpy import json_default

SCHEMA = "shaketable-rig/study/1"
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"

COR_DTYPE = np.dtype([("body_index", "<i4"), ("angle_deg", "<f8"), ("overturned", "<i8"), ("desired", "<i8"),
                      ("cor", "<f8")])
ESTIMATOR_DTYPE = np.dtype([
    ("body_index", "<i4"), ("equation", "S4"), ("coefficients", "S6"), ("max_difference", "<f8"),
    ("absolute_area", "<f8"), ("error", "<f8"), ("paper_max_difference", "<f8"), ("paper_absolute_area", "<f8"),
    ("paper_error", "<f8"),
])


class StudyFileError(ValueError):
    """A study file that cannot be written or read; the message names the file and what is wrong."""


def _nan(x: float | None) -> float:
    return math.nan if x is None else float(x)


def _json(obj: Any) -> str:
    return json.dumps(obj, default=json_default)


def direction_array(res: StudyResult) -> np.ndarray:
    """The study's directions as int8 (bodies, records, signs, angles) — its scene order reshaped."""
    shape = (len(res.bodies), len(res.records), len(res.signs), len(res.angles))
    return np.asarray(res.direction, dtype=np.int8).reshape(shape)


def _cor_table(summary: dict[str, Any], n_angles: int) -> np.ndarray:
    rows = [(i // n_angles, r["angle_deg"], r["overturned"], r["desired"], _nan(r["cor"]))
            for i, r in enumerate(summary["cor"])]
    rows += [(-1, r["angle_deg"], r["overturned"], r["desired"], _nan(r["cor"])) for r in summary["average_cor"]]
    return np.array(rows, dtype=COR_DTYPE)


def _estimator_table(summary: dict[str, Any]) -> np.ndarray:
    rows = []
    for r in summary["estimators"]:
        paper = r.get("paper") or {}
        rows.append((r["body_index"], r["equation"].encode(), r["coefficients"].encode(), _nan(r["max_difference"]),
                     _nan(r["absolute_area"]), _nan(r["error"]), _nan(paper.get("max_difference")),
                     _nan(paper.get("absolute_area")), _nan(paper.get("error"))))
    return np.array(rows, dtype=ESTIMATOR_DTYPE)


def _fit_attrs(group: Any, fit: dict[str, Any], names: tuple[str, ...], paper: dict[str, Any],
               paper_error: float | None) -> None:
    for key in names:
        group.attrs[f"paper_{key}"] = float(paper[key])
    group.attrs["paper_eq12_error"] = _nan(paper_error)
    if "error" in fit:
        group.attrs["error"] = str(fit["error"])
        return
    cis = fit["ci"] if "ci" in fit else {k: fit.get(f"{k}_ci") for k in names}
    for key in names:
        group.attrs[key] = float(fit[key])
        ci = cis.get(key)
        group.attrs[f"{key}_ci_low"], group.attrs[f"{key}_ci_high"] = (math.nan, math.nan) if ci is None else ci
    group.attrs["rms"] = float(fit["rms"])
    group.attrs["n"] = int(fit["n"])
    group.attrs["c2_fixed"] = bool(fit["c2_fixed"])
    group.attrs["eq12_error"] = _nan(fit.get("eq12_error"))


def _write_contents(h5: Any, res: StudyResult, summary: dict[str, Any]) -> None:
    h5.attrs["schema"] = SCHEMA
    h5.attrs["software_version"] = __version__
    h5.attrs["created"] = datetime.now(UTC).isoformat(timespec="seconds")
    h5.attrs["model"] = res.model
    h5.attrs["restitution"] = str(res.settings.get("restitution", 0.0))
    h5.attrs["friction"] = float(res.settings.get("friction", math.nan))
    h5.attrs["records"] = _json(list(res.records))
    h5.attrs["bodies"] = _json([{"b": b.b, "h": b.h, "name": b.name,
                                 **({} if b.b_cg is None else {"b_cg": b.b_cg}),
                                 **({} if b.h_cg is None else {"h_cg": b.h_cg})} for b in res.bodies])
    h5.attrs["angles_deg"] = np.degrees(np.asarray(res.angles, dtype=float))
    h5.attrs["signs"] = np.asarray(res.signs, dtype=np.int8)
    h5.attrs["seconds"] = float(res.seconds)
    h5.attrs["scenes"] = int(res.scenes)
    h5.attrs["where"] = str(res.settings.get("where", "local"))
    h5.attrs["summary"] = _json(summary)
    h5.create_dataset("direction", data=direction_array(res), compression="gzip", shuffle=True)
    h5.create_dataset("cor", data=_cor_table(summary, len(res.angles)))
    fits = h5.create_group("fits")
    paper = summary["paper"]
    _fit_attrs(fits.create_group("gcor"), summary["gcor"], ("c1", "c2"), paper["gcor"],
               summary["gcor_paper"]["eq12_error"])
    _fit_attrs(fits.create_group("scor"), summary["scor"], ("k1", "k2", "k3", "c2"), paper["scor"],
               summary["scor_paper"]["eq12_error"])
    h5.create_dataset("estimators", data=_estimator_table(summary))


def write_study(res: StudyResult, summary: dict[str, Any], path: str | Path) -> Path:
    """Save ``res`` and its ``summary`` (:func:`rig.study_summary.study_summary`) to ``path``, replacing an
    existing file atomically: a temporary file in the same directory, renamed into place when complete."""
    import h5py

    path = Path(path)
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(8)}.tmp")
    try:
        with h5py.File(tmp, "w") as h5:
            _write_contents(h5, res, summary)
        with tmp.open("r+b") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        raise StudyFileError(f"{path}: cannot write ({exc.strerror or exc})") from None
    finally:
        tmp.unlink(missing_ok=True)
    return path


@dataclass
class SavedStudy:
    """A study file's contents: attributes as Python values, the direction array and the tables."""

    path: Path
    attrs: dict[str, Any]
    """Root attributes; ``records`` and ``bodies`` parsed from JSON, ``summary`` as a dict."""
    direction: np.ndarray
    """int8 (bodies, records, signs, angles)."""
    cor: np.ndarray
    """``COR_DTYPE`` rows (body_index −1: the body average)."""
    fits: dict[str, dict[str, Any]]
    """``{"gcor": attrs, "scor": attrs}`` of the ``fits`` groups."""
    estimators: np.ndarray
    """``ESTIMATOR_DTYPE`` rows (Table III)."""

    @property
    def bodies(self) -> list[Body]:
        return [Body(b=d["b"], h=d["h"], name=d.get("name", ""), b_cg=d.get("b_cg"), h_cg=d.get("h_cg"))
                for d in self.attrs["bodies"]]

    @property
    def records(self) -> list[str]:
        return list(self.attrs["records"])

    @property
    def angles_rad(self) -> np.ndarray:
        return np.radians(np.asarray(self.attrs["angles_deg"], dtype=float))

    def cor_from_direction(self) -> list[dict[str, Any]]:
        """COR per body and angle recomputed from ``direction`` (body-major, as the ``cor`` table)."""
        nb, _, _, na = self.direction.shape
        return [{"body_index": j, "angle_deg": float(self.attrs["angles_deg"][m]),
                 **cor_counts(self.direction[j, :, :, m])} for j in range(nb) for m in range(na)]

    def coefficients(self, equation: str) -> tuple[float, ...]:
        """The fitted coefficients: (c1, c2) for GCOR, (k1, k2, k3, c2) for SCOR, as ``rig design`` takes them."""
        key = equation.lower()
        names = ("c1", "c2") if key == "gcor" else ("k1", "k2", "k3", "c2")
        fit = self.fits.get(key, {})
        if "error" in fit or not all(n in fit for n in names):
            why = f": the fit failed ({fit['error']})" if "error" in fit else ""
            raise StudyFileError(f"{self.path}: no fitted {equation.upper()} coefficients{why}")
        return tuple(float(fit[n]) for n in names)


def is_study_file(path: str | Path) -> bool:
    """Whether ``path`` starts with the HDF5 signature (a study file, as opposed to a JSON summary)."""
    try:
        with Path(path).open("rb") as f:
            return f.read(len(HDF5_SIGNATURE)) == HDF5_SIGNATURE
    except OSError:
        return False


def _attr(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.generic):
        return value.item()
    return value


def read_study(path: str | Path) -> SavedStudy:
    """Read a file written by :func:`write_study`. Raises :class:`StudyFileError` naming what is wrong."""
    import h5py

    path = Path(path)
    expected = f"a study file (schema {SCHEMA}) written by `rig study -o`"
    try:
        with h5py.File(path, "r") as h5:
            attrs = {k: _attr(v) for k, v in h5.attrs.items()}
            if attrs.get("schema") != SCHEMA:
                raise StudyFileError(f"{path}: schema is {attrs.get('schema')!r}; expected {expected}")
            for key in ("records", "bodies", "summary"):
                attrs[key] = json.loads(attrs[key])
            direction = np.asarray(h5["direction"][()], dtype=np.int8)
            cor = h5["cor"][()]
            fits = {name: {k: _attr(v) for k, v in h5["fits"][name].attrs.items()} for name in ("gcor", "scor")}
            est = h5["estimators"][()]
    except StudyFileError:
        raise
    except FileNotFoundError:
        raise StudyFileError(f"{path}: no such file") from None
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise StudyFileError(f"{path}: unreadable ({exc}); expected {expected}") from None
    shape = (len(attrs["bodies"]), len(attrs["records"]), len(attrs["signs"]), len(attrs["angles_deg"]))
    if direction.shape != shape:
        raise StudyFileError(f"{path}: direction has shape {direction.shape}, the attributes say {shape}")
    return SavedStudy(path=path, attrs=attrs, direction=direction, cor=cor, fits=fits, estimators=est)
