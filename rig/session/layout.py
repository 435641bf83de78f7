"""Writing the session file's structure (see `rig.session.schema`): the root, a run group, a run's end.

These functions only create objects and attributes; `rig.session.atomic` makes each call sequence one atomic
change of the file. They never read variable-length data of the file, so HDF5 puts new strings in a new
global-heap collection (new space) rather than rewriting an existing one in place.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

import h5py
import numpy as np

from analysis.table.sensors import SensorSheet, TiltSheet

from . import checksums, schema
from .hdf5props import EST_RUN_LINKS, EST_RUNS, create_group

#: HDF5 fixed-length string attributes hold at least one byte.
_FIXED_LEN = 16


def attr_value(name: str, value: Any) -> Any:
    """An attribute value h5py stores natively: bool/int/float/str scalars as such, lists and dicts as JSON
    text. ValueError for anything else (and for non-finite numbers inside JSON)."""
    if isinstance(value, bool | np.bool_):
        return np.bool_(value)
    if isinstance(value, int | np.integer):
        return np.int64(value)
    if isinstance(value, float | np.floating):
        return np.float64(value)
    if isinstance(value, str):
        return value
    if isinstance(value, list | tuple | dict):
        try:
            return json.dumps(value, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"attribute {name!r}: {exc}; expected JSON-able data") from None
    raise ValueError(f"attribute {name!r} is a {type(value).__name__}; expected a bool, int, float, str, "
                     "list or dict")


def create_root(h5: h5py.File, *, software_version: str, created: str, rig_config: str, sequence: str,
                table: str | None = None) -> None:
    """Root attributes (``table`` only when given) and the empty ``/runs`` group (compact links, sized for
    `EST_RUNS` runs in page 0)."""
    h5.attrs["schema"] = schema.SCHEMA
    h5.attrs["software_version"] = software_version
    h5.attrs["created"] = created
    h5.attrs["rig_config"] = rig_config
    h5.attrs["sequence"] = sequence
    if table is not None:
        h5.attrs["table"] = table
    create_group(h5, "runs", links=EST_RUNS)


def _columns(ds: h5py.Dataset, columns: Sequence[str], units: Sequence[str]) -> None:
    ds.attrs["columns"] = ",".join(columns)
    ds.attrs["units"] = ",".join(units)


def _growing(parent: h5py.Group, name: str, width: int, chunk: int, data: np.ndarray | None = None) -> h5py.Dataset:
    """A float64 (n, width) dataset, chunked, unlimited along rows (SWMR appends), uncompressed (a chunk keeps its
    address while it fills, so rewriting it never moves samples already on disk)."""
    initial = np.zeros((0, width)) if data is None else data
    return parent.create_dataset(name, data=initial, maxshape=(None, width), chunks=(chunk, width), dtype="<f8",
                                 track_times=False)


def _table(parent: h5py.Group, name: str, dtype: np.dtype, rows: np.ndarray | None = None) -> h5py.Dataset:
    initial = np.zeros(0, dtype=dtype) if rows is None else rows
    return parent.create_dataset(name, data=initial, maxshape=(None,), chunks=(schema.TABLE_CHUNK,), dtype=dtype,
                                 track_times=False)


def create_run(runs: h5py.Group, name: str, *, plan_index: int, attempt: int, record: str, scale_factor: float,
               angle_deg: float, started: str, commanded: np.ndarray, bodies: np.ndarray, sensors: Sequence[str],
               attrs: Mapping[str, Any], sheets: Mapping[str, SensorSheet] | None = None,
               tilt_sheets: Mapping[str, TiltSheet] | None = None) -> None:
    """The run group ``runs/name`` with its attributes (status ``"running"``), all its datasets and its checksum
    table (`rig.session.checksums`) holding the checksums of the rows it is created with; ``sheets``: the
    calibration sheets (``analysis.table.sensors``) of the sensors that have one, stored as attributes of their
    ``accel/<sensor>`` datasets."""
    group = create_group(runs, name, links=EST_RUN_LINKS, name_len=16)
    group.attrs["record"] = record
    group.attrs["scale_factor"] = np.float64(scale_factor)
    group.attrs["angle_deg"] = np.float64(angle_deg)
    group.attrs["plan_index"] = np.int64(plan_index)
    group.attrs["attempt"] = np.int64(attempt)
    group.attrs["started"] = started
    group.attrs["sensors"] = json.dumps(list(sensors))
    # fixed-length while running: the end replaces them by changing this header only (schema docstring)
    group.attrs.create("status", np.bytes_(schema.RUNNING.encode()), dtype=h5py.string_dtype("utf-8", _FIXED_LEN))
    group.attrs.create("ended", np.bytes_(b""), dtype=h5py.string_dtype("utf-8", _FIXED_LEN))
    for key, value in attrs.items():
        group.attrs[key] = value
    group.attrs["attribute_units"] = json.dumps({key: unit for key, unit in schema.RUN_ATTR_UNITS.items()
                                                 if key in group.attrs})
    _columns(_growing(group, "commanded", 7, schema.POSE_CHUNK, commanded), schema.POSE_COLUMNS, schema.POSE_UNITS)
    _columns(_growing(group, "pose", 7, schema.POSE_CHUNK), schema.POSE_COLUMNS, schema.POSE_UNITS)
    _columns(_growing(group, "following_error", 7, schema.POSE_CHUNK), schema.FOLLOWING_ERROR_COLUMNS,
             schema.FOLLOWING_ERROR_UNITS)
    accel = create_group(group, "accel")
    for sensor in sensors:
        dataset = _growing(accel, sensor, 4, schema.ACCEL_CHUNK)
        _columns(dataset, schema.ACCEL_COLUMNS, schema.ACCEL_UNITS)
        if sheets and sensor in sheets:
            _sheet_attrs(dataset, sheets[sensor])
    tilt = create_group(group, "tilt")
    for body_id in bodies["body_id"]:
        dataset = _growing(tilt, str(int(body_id)), 2, schema.TILT_CHUNK)
        _columns(dataset, schema.TILT_COLUMNS, schema.TILT_UNITS)
        if tilt_sheets and str(int(body_id)) in tilt_sheets:
            _tilt_sheet_attrs(dataset, tilt_sheets[str(int(body_id))])
    for table, dtype, units, rows in (("detections", schema.DETECTION, schema.DETECTION_UNITS, None),
                                      ("faults", schema.FAULT, schema.FAULT_UNITS, None),
                                      ("events", schema.EVENT, schema.EVENT_UNITS, None),
                                      ("bodies", schema.BODY, schema.BODY_UNITS, bodies)):
        _columns(_table(group, table, dtype, rows), dtype.names or (), units)
    table = checksums.create_table(group, {"commanded": np.asarray(commanded, dtype="<f8"),
                                           "bodies": np.asarray(bodies, dtype=schema.BODY)})
    _columns(table, checksums.CHECKSUM.names or (), checksums.CHECKSUM_UNITS)


def _sheet_attrs(dataset: h5py.Dataset, sheet: SensorSheet) -> None:
    """A sensor's sheet as attributes of its dataset: ``place_m`` (x, y, z [m], plate frame), ``axes`` (the plate
    axis of each of its axes, comma-separated), ``range_m_s2`` (full scale [m/s²], ±), ``sensitivity`` (in
    ``sensitivity_unit``), ``model``, ``serial``, ``calibrated`` and ``due`` (ISO dates)."""
    dataset.attrs["place_m"] = np.asarray(sheet.place_m, dtype="<f8")
    dataset.attrs["axes"] = ",".join(sheet.axes)
    dataset.attrs["range_m_s2"] = np.float64(sheet.range_m_s2)
    dataset.attrs["sensitivity"] = np.float64(sheet.sensitivity)
    dataset.attrs["sensitivity_unit"] = sheet.sensitivity_unit
    dataset.attrs["model"] = sheet.model
    dataset.attrs["serial"] = sheet.serial
    dataset.attrs["calibrated"] = sheet.calibrated.isoformat()
    dataset.attrs["due"] = sheet.due.isoformat()


def _tilt_sheet_attrs(dataset: h5py.Dataset, sheet: TiltSheet) -> None:
    """A tilt sensor's sheet as attributes of its body's dataset: ``range_rad`` (full scale [rad], ±), ``model``,
    ``serial``, ``calibrated`` and ``due`` (ISO dates)."""
    dataset.attrs["range_rad"] = np.float64(sheet.range_rad)
    dataset.attrs["model"] = sheet.model
    dataset.attrs["serial"] = sheet.serial
    dataset.attrs["calibrated"] = sheet.calibrated.isoformat()
    dataset.attrs["due"] = sheet.due.isoformat()


def finish_run(group: h5py.Group, *, status: str, ended: str, attrs: Mapping[str, Any]) -> None:
    """Final ``status`` and ``ended`` (as ordinary strings) and extra attributes of a run group."""
    for key in ("status", "ended"):
        if key in group.attrs:
            del group.attrs[key]
    group.attrs["status"] = status
    group.attrs["ended"] = ended
    for key, value in attrs.items():
        group.attrs[key] = value
