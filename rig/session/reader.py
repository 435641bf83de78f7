"""Reading session files, also while they are being written and after their writer was killed.

How any program must open a session file: ``h5py.File(path, "r", swmr=True)`` (h5py's ``locking=False`` is
also fine). While a run is recorded the file is in HDF5 SWMR-write mode and its superblock says so; a reader
without ``swmr=True`` is refused ("file is already open for write") — also after a writer was killed, until
`SessionLog.resume` clears the flag. A SWMR reader sees each dataset grow after ``Dataset.refresh()``; run
groups added after it opened the file appear when it opens the file again. In the *writer's* process a reader
must not keep the file open across `SessionLog.begin_run` (HDF5 shares one open file per process and cannot
turn a read-only handle into the SWMR writer): use `read_session`, which opens and closes the file.

A metadata block may be caught half-written by a reader at the moment the writer replaces it (HDF5's
checksums detect it); `open_session` and `read_session` retry for a while before giving up, but only while a live
writer holds the file: a file no one writes that fails to read is damaged, and is said to be at once
(`DamagedFileError`, after the checks of `rig.session.check`; HDF5's own retries are bounded, so no read hangs).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from . import check, checksums, schema, superblock
from .errors import DamagedFileError, SessionError
from .locks import writer_holds

#: How long `read_session` keeps retrying a file caught mid-update [s].
RETRY_SECONDS = 5.0
_RETRYABLE = (OSError, RuntimeError, KeyError, ValueError)

#: `writer_state` values.
CLOSED, WRITING, CRASHED = "closed", "writing", "crashed"


def _writer_live(path: Path) -> bool:
    """Whether a live session log holds ``path``, so that a failed read may have met it mid-update."""
    try:
        return writer_holds(path)
    except SessionError:
        return False


def open_session(path: str | os.PathLike[str], *, timeout: float = RETRY_SECONDS) -> h5py.File:
    """Open a session file for reading the way every reader should (SWMR read, no HDF5 file lock, HDF5's retries
    bounded: `rig.session.check`). A file that fails the checks or that HDF5 cannot open is retried for up to
    ``timeout`` seconds only while a live writer holds it (it may be caught mid-update); otherwise, and after
    that, `DamagedFileError` (a `SessionError`) naming the file and what is wrong."""
    path = Path(path)
    if not path.is_file():
        raise SessionError(f"{path}: no such session file")
    deadline = time.monotonic() + timeout
    delay = 0.005
    while True:
        try:
            check.check_session(path)
            return check.open_read(path)
        except DamagedFileError:
            if time.monotonic() >= deadline or not _writer_live(path):
                raise
        except OSError as exc:
            if time.monotonic() >= deadline or not _writer_live(path):
                raise check.hdf5_error(path, exc) from None
        time.sleep(delay)
        delay = min(delay * 2, 0.2)


def plain(value: Any) -> Any:
    """h5py/numpy values as plain Python: bytes → str, numpy scalars → int/float/bool, arrays kept (string arrays
    → lists of str)."""
    if isinstance(value, bytes | np.bytes_):
        return bytes(value).decode("utf-8", "replace")
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "SOU":
            return [plain(v) for v in value.tolist()]
        return value
    if isinstance(value, np.generic):
        return value.item()
    return value


def child(group: h5py.Group, name: str) -> Any:
    """``group[name]``, or None if ``group`` has no such link. Unlike h5py's ``get``, an object that HDF5 cannot
    read (a damaged header) raises instead of passing for a missing one."""
    return group[name] if name in group else None  # noqa: SIM401 (h5py.Group.get hides a damaged object)


def _rows(data: np.ndarray) -> list[dict[str, Any]]:
    """Compound rows as dicts of plain values (bytes → str)."""
    names = data.dtype.names or ()
    return [{name: plain(row[name]) for name in names} for row in np.atleast_1d(data)]


def records(ds: h5py.Dataset) -> list[dict[str, Any]]:
    """A compound dataset's rows as dicts of plain values (bytes → str)."""
    return _rows(ds[()])


def attributes(obj: h5py.HLObject) -> dict[str, Any]:
    """An object's attributes as plain values."""
    return {key: plain(obj.attrs[key]) for key in obj.attrs}


def _tree(group: h5py.Group) -> dict[str, Any]:
    """Any group (e.g. ``analysis``) as nested dicts: attributes under ``"attrs"``, datasets as arrays/records."""
    out: dict[str, Any] = {"attrs": attributes(group)}
    for key, node in group.items():
        if isinstance(node, h5py.Group):
            out[key] = _tree(node)
        elif node.dtype.names:
            out[key] = records(node)
        else:
            out[key] = plain(node[()])
    return out


def _raw_datasets(group: h5py.Group) -> dict[str, np.ndarray]:
    """The run's sample datasets as stored, by name inside the run (``accel/plate``, ``tilt/1``, ``events``…)."""
    raw: dict[str, np.ndarray] = {}
    for key in ("commanded", "pose", "following_error", "detections", "bodies", "faults", "events"):
        if key in group:
            raw[key] = group[key][()]
    for sub in ("accel", "tilt"):
        if sub in group:
            raw.update({f"{sub}/{name}": ds[()] for name, ds in group[sub].items()})
    return raw


def read_run(group: h5py.Group, name: str, data: bool = True, *, path: str | os.PathLike[str] = "") -> dict[str, Any]:
    """One run group as `read_session` gives its runs (with or without ``data``). With ``data``, the samples are
    checked against the run's checksums (`rig.session.checksums`: `DamagedFileError` naming the file ``path``, the
    run, the dataset and the rows) and ``checksums`` says what was found: ``state`` ``"verified"`` or ``"not
    checksummed"`` (a run written before checksums), ``unverified`` {dataset: [first, end)} rows after the last
    checksummed block (a killed writer's last flush, or a run being recorded)."""
    attrs = attributes(group)
    run: dict[str, Any] = {"name": name}
    for key in ("record", "scale_factor", "angle_deg", "status", "started", "ended", "plan_index", "attempt"):
        run[key] = attrs.get(key)
    try:
        run["sensors"] = json.loads(attrs.get("sensors", "[]"))
    except (TypeError, ValueError):
        run["sensors"] = sorted(child(group, "accel") or {})
    run["attrs"] = attrs
    if not data:
        accel = child(group, "accel") or {}
        run["samples"] = {f"accel/{s}": accel[s].shape[0] for s in accel}
        return run
    blocks = checksums.read_table(group)  # before the datasets (`checksums.read_table`)
    raw = _raw_datasets(group)
    found = checksums.verify(Path(path), name, blocks, raw, recording=run["status"] == schema.RUNNING)
    run["checksums"] = {"state": found.state, "unverified": {key: list(span) for key, span in found.unverified.items()}}
    for key in ("commanded", "pose", "following_error"):  # following_error: absent in older files, empty
        run[key] = raw.get(key, np.zeros((0, 7)))
    run["accel"] = {key.split("/", 1)[1]: rows for key, rows in raw.items() if key.startswith("accel/")}
    run["tilt"] = {int(key.split("/", 1)[1]): rows for key, rows in raw.items() if key.startswith("tilt/")}
    for key in ("detections", "bodies", "faults", "events"):
        run[key] = _rows(raw[key]) if key in raw else []
    if "analysis" in group:
        run["analysis"] = _tree(group["analysis"])
    return run


def _read(path: Path, data: bool) -> dict[str, Any]:
    with open_session(path, timeout=0.0) as h5:
        attrs = attributes(h5)
        if attrs.get("schema") != schema.SCHEMA:
            raise SessionError(f"{path}: schema attribute is {attrs.get('schema')!r}; expected {schema.SCHEMA!r}")
        out: dict[str, Any] = {"path": str(path), "schema": attrs["schema"]}
        for key in ("software_version", "created"):
            out[key] = attrs.get(key)
        for key in ("rig_config", "sequence"):
            out[key] = json.loads(attrs[key]) if isinstance(attrs.get(key), str) else None
        out["attrs"] = attrs
        runs = child(h5, "runs")
        out["runs"] = [read_run(runs[name], name, data, path=path) for name in sorted(runs)] if runs is not None else []
        return out


def read_session(path: str | os.PathLike[str], *, data: bool = True, timeout: float = RETRY_SECONDS) -> dict[str, Any]:
    """A session file as plain data (also while it is written): ``{"path", "schema", "software_version", "created",
    "rig_config": dict, "sequence": dict, "attrs", "runs": [...]}``; each run a dict with ``name``, ``record``,
    ``scale_factor``, ``angle_deg``, ``status``, ``started``, ``ended``, ``plan_index``, ``attempt``, ``sensors``,
    ``attrs`` and, with ``data``, ``commanded``/``pose``/``following_error`` (n, 7) arrays, ``accel`` {sensor:
    (m, 4) array}, ``tilt`` {body_id: (l, 2) array of t, angle} (empty without tilt sensors),
    ``detections``/``bodies``/``faults``/``events`` as lists of dicts, ``analysis`` if present (without
    ``data``: ``samples``, the row count per accelerometer). Strings are ``str``.

    A read that fails is retried for up to ``timeout`` seconds while a live writer holds the file (`open_session`);
    otherwise `DamagedFileError` names the file and what HDF5 could not read."""
    path = Path(path)
    deadline = time.monotonic() + timeout
    delay = 0.005
    while True:
        try:
            return _read(path, data)
        except DamagedFileError:
            if time.monotonic() >= deadline or not _writer_live(path):
                raise
        except SessionError:
            raise
        except _RETRYABLE as exc:
            if time.monotonic() >= deadline or not _writer_live(path):
                raise check.hdf5_error(path, exc) from None
        time.sleep(delay)
        delay = min(delay * 2, 0.2)


def iter_runs(path: str | os.PathLike[str]) -> Iterator[dict[str, Any]]:
    """The session's runs in order, each read (as `read_session` with ``data``) only when it is asked for: one
    run's samples in memory at a time, for campaigns of hundreds of MB. The file stays open meanwhile."""
    with open_session(path) as h5:
        try:
            runs = child(h5, "runs")
            names = sorted(runs) if runs is not None else []
        except _RETRYABLE as exc:
            raise check.hdf5_error(path, exc, "/runs") from None
        for name in names:
            try:
                run = read_run(runs[name], name, path=path)
            except _RETRYABLE as exc:
                raise check.hdf5_error(path, exc, f"/runs/{name}") from None
            yield run


def writer_flags(path: str | os.PathLike[str]) -> int:
    """The superblock's consistency flags: 0 if no writer has the file open (or one closed it cleanly), non-zero
    while a run is recorded or after a writer died mid-run (until resumed)."""
    with open(path, "rb") as f:
        return superblock.parse(f.read(superblock.SIZE), path).flags


def writer_state(path: str | os.PathLike[str]) -> str:
    """``"writing"`` if a live session log holds the file (`rig.session.locks`), ``"crashed"`` if its writer flags
    are set but no writer holds it (the writer was killed: `rig.session.recover`), else ``"closed"``."""
    path = Path(path)
    if writer_holds(path):
        return WRITING
    return CRASHED if writer_flags(path) else CLOSED


def list_sessions(directory: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """Session files (``*.h5``/``*.hdf5`` with the session schema) in ``directory``, oldest first: ``path``,
    ``created``, ``software_version``, ``runs`` (count), ``statuses`` ({status: count}), ``open_for_write``
    (a run is being recorded, or its writer died and the session was not resumed), ``state`` (`writer_state`:
    ``"writing"``, ``"crashed"`` or ``"closed"``). Other files are skipped."""
    found = []
    for path in sorted(Path(directory).iterdir()):
        if path.name.startswith(".") or path.suffix.lower() not in (".h5", ".hdf5") or not path.is_file():
            continue
        try:
            flags = writer_flags(path)
            state = writer_state(path)
            session = read_session(path, data=False, timeout=1.0)
        except (SessionError, OSError, ValueError):
            continue
        statuses: dict[str, int] = {}
        for run in session["runs"]:
            statuses[str(run["status"])] = statuses.get(str(run["status"]), 0) + 1
        found.append({"path": str(path), "created": session["created"],
                      "software_version": session["software_version"], "runs": len(session["runs"]),
                      "statuses": statuses, "open_for_write": bool(flags),
                      "state": state})
    found.sort(key=lambda s: (str(s["created"]), s["path"]))
    return found
