"""`SessionLog`: one session file, written crash-safely (the run being recorded: `rig.session.run.RunLog`).

Life of a session file (layout: `rig.session.schema`):

* `SessionLog.create` writes a complete small file under a temporary name and hard-links it to the session
  name, so the name appears with a whole file or not at all, and an existing file is never replaced.
* `SessionLog.begin_run` adds the run group with all its datasets in one atomic transaction
  (`rig.session.atomic`), then opens the file in HDF5 SWMR-write mode; a `BlockWriter` thread appends the
  samples and flushes at least every ``flush_interval`` seconds (default 0.25 s).
* `RunLog.end` stops the writer (last flush), closes the SWMR file and sets the final attributes in another
  atomic transaction.
* `SessionLog.resume` reopens a session after a crash: clears the "open for write" flags a killed SWMR writer
  leaves in the superblock, marks runs still ``"running"`` as ``"interrupted"``.

The writer holds an exclusive lock on the file (`rig.session.locks`) from create/resume to `close`.
"""

from __future__ import annotations

import json
import math
import os
import secrets
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from analysis.table.configuration import configuration_from_dict
from analysis.table.sensors import SensorSheets

from . import check, checksums, failpoints, layout, schema
from .atomic import SessionFile, fsync_dir, remove_stale_temporaries
from .errors import SessionError, SessionExistsError
from .hdf5props import LIBVER, PAGE, file_access
from .locks import lock_fd, open_locked
from .reader import open_session
from .run import RunLog
from .runinfo import RunInfo, run_info, text
from .writer import BlockWriter

#: Default time between two flushes of a run's samples [s].
FLUSH_INTERVAL = 0.25
#: Longest flush interval accepted [s] (the issue: "flushed at least once a second").
MAX_FLUSH_INTERVAL = 0.5


def _open_swmr(path: Path) -> h5py.File:
    """The file in SWMR-write mode from the start (the superblock gets both "write" and "SWMR write" flags at once,
    so SWMR readers can open it at every moment, also if this process dies)."""
    try:
        fid = h5py.h5f.open(os.fsencode(path), h5py.h5f.ACC_RDWR | h5py.h5f.ACC_SWMR_WRITE, fapl=file_access())
    except OSError as exc:
        hint = ""
        if "already open" in str(exc):
            hint = ("; this process still has it open for reading (h5py.File/open_session): close such handles "
                    "before begin_run, or read with read_session, which opens and closes the file")
        raise SessionError(f"{path}: cannot open for SWMR writing ({exc}){hint}") from None
    return h5py.File(fid)


def _check_schema(path: Path) -> None:
    """SessionError unless the file's root ``schema`` attribute is ours (read as a SWMR reader: works whether or not
    a killed writer left the "open for write" flags)."""
    try:
        with open_session(path, timeout=1.0) as h5:
            found = h5.attrs.get("schema")
    except (OSError, RuntimeError, KeyError, ValueError) as exc:
        raise check.hdf5_error(path, exc, "its root attributes") from None
    if text(found) != schema.SCHEMA:
        raise SessionError(f"{path}: schema attribute is {found!r}; expected {schema.SCHEMA!r}")


def _read_file(path: Path) -> tuple[dict[str, Any], list[RunInfo]]:
    """Root attributes (rig_config and sequence parsed) and run groups of a session file that no one else writes
    (read before a transaction)."""
    try:
        with check.open_read(path, swmr=False) as h5:
            found = h5.attrs.get("schema")
            if text(found) != schema.SCHEMA:
                raise SessionError(f"{path}: schema attribute is {found!r}; expected {schema.SCHEMA!r}")
            if "runs" not in h5:
                raise SessionError(f"{path}: no /runs group; expected a {schema.SCHEMA} session file")
            root: dict[str, Any] = {key: text(h5.attrs.get(key, "")) for key in ("software_version", "created",
                                                                                 "rig_config", "sequence", "table")}
            for key in ("rig_config", "sequence"):
                root[key] = json.loads(root[key]) if root[key] else {}
            root["table"] = json.loads(root["table"]) if root["table"] else None
            return root, [run_info(name, h5["runs"][name].attrs) for name in sorted(h5["runs"])]
    except (OSError, RuntimeError, KeyError, ValueError) as exc:
        raise check.hdf5_error(path, exc) from None


def _interval(value: float) -> float:
    if not 0.0 < value <= MAX_FLUSH_INTERVAL:
        raise SessionError(f"flush_interval {value!r} s; expected 0 < interval <= {MAX_FLUSH_INTERVAL} (samples "
                           "must reach the disk at least once a second)")
    return float(value)


def _jsontext(value: Any, what: str, path: Path) -> str:
    try:
        return json.dumps(value, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise SessionError(f"{path}: {what} is not JSON-serialisable ({exc}); expected plain data") from None


class SessionLog:
    """The session file being written (see the module docstring). Use `create` or `resume`."""

    def __init__(self, file: SessionFile, runs: list[RunInfo], flush_interval: float, root: dict[str, Any]) -> None:
        self._file = file
        self._root = root
        self._runs = runs
        self._flush_interval = flush_interval
        self._active: RunLog | None = None

    # -- opening -----------------------------------------------------------------------------------------
    @classmethod
    def create(cls, path: str | os.PathLike[str], rig_config: dict, sequence: dict, software_version: str, *,
               flush_interval: float = FLUSH_INTERVAL, table: dict | None = None) -> SessionLog:
        """Create a new session file at ``path``; `SessionExistsError` if anything exists there (never replaced).

        ``flush_interval``: time between two flushes of a run's samples [s], at most `MAX_FLUSH_INTERVAL`;
        ``table``: where the session plays (root attribute ``table``, `rig.session.schema`)."""
        flush_interval = _interval(flush_interval)
        path = Path(path)
        if path.exists() or path.is_symlink():
            raise SessionExistsError(f"{path}: already exists; a session file is never overwritten, choose a new "
                                     "file name (or resume that session)")
        if not path.parent.is_dir():
            raise SessionError(f"{path}: directory {path.parent} does not exist")
        config_json = _jsontext(rig_config, "rig_config", path)
        sequence_json = _jsontext(sequence, "sequence", path)
        table_json = None if table is None else _jsontext(table, "table", path)
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(6)}.creating")
        root = {"software_version": str(software_version), "created": schema.iso_now(),
                "rig_config": json.loads(config_json), "sequence": json.loads(sequence_json),
                "table": None if table_json is None else json.loads(table_json)}
        fd = -1
        try:
            with h5py.File(tmp, "w-", libver=LIBVER, fs_strategy="page", fs_page_size=PAGE, locking=False) as h5:
                layout.create_root(h5, software_version=root["software_version"], created=root["created"],
                                   rig_config=config_json, sequence=sequence_json, table=table_json)
            fd = os.open(tmp, os.O_RDWR | os.O_CLOEXEC)
            os.fsync(fd)
            lock_fd(fd, path)
            try:
                os.link(tmp, path)  # fails if the name exists, even if it appeared since the check above
            except FileExistsError:
                raise SessionExistsError(f"{path}: already exists; a session file is never overwritten, choose a "
                                         "new file name") from None
            except OSError:  # no hard links on this file system: check, then rename
                if path.exists():
                    raise SessionExistsError(f"{path}: already exists; a session file is never overwritten") from None
                os.rename(tmp, path)
        except BaseException as exc:
            if fd >= 0:
                os.close(fd)
            tmp.unlink(missing_ok=True)
            if isinstance(exc, OSError) and not isinstance(exc, SessionError):
                raise SessionError(f"{path}: cannot create the session file ({exc})") from None
            raise
        tmp.unlink(missing_ok=True)
        fsync_dir(path.parent)
        return cls(SessionFile(path, fd), [], flush_interval, root)

    @classmethod
    def resume(cls, path: str | os.PathLike[str], *, flush_interval: float = FLUSH_INTERVAL) -> SessionLog:
        """Reopen a session file for more runs; runs still ``"running"`` become ``"interrupted"`` (``ended`` = now)."""
        flush_interval = _interval(flush_interval)
        path = Path(path)
        file = SessionFile(path, open_locked(path))
        try:
            file.superblock()  # an HDF5 file of ours (SessionError otherwise) …
            _check_schema(path)  # … and a session file, before anything is changed in it
            remove_stale_temporaries(path)
            file.clear_open_flags()
            root, runs = _read_file(path)
            log = cls(file, runs, flush_interval, root)
            cut = [run for run in runs if run.status == schema.RUNNING]
            if cut:
                ended = schema.iso_now()
                with file.transaction() as h5:
                    for run in cut:
                        layout.finish_run(h5["runs"][run.name], status="interrupted", ended=ended, attrs={})
                done = {run.name: replace(run, status="interrupted", ended=ended) for run in cut}
                log._runs = [done.get(run.name, run) for run in runs]
        except BaseException:
            file.close()
            raise
        return log

    # -- queries ------------------------------------------------------------------------------------------
    @property
    def path(self) -> Path:
        return self._file.path

    @property
    def rig_config(self) -> dict:
        """The rig configuration stored at creation (parsed from the root attribute's JSON)."""
        return self._root["rig_config"]

    @property
    def sequence(self) -> dict:
        """The sequence stored at creation (parsed from the root attribute's JSON)."""
        return self._root["sequence"]

    @property
    def table(self) -> dict | None:
        """Where the session plays, as stored at creation (root attribute ``table``), or None (not stored)."""
        return self._root["table"]

    def sensor_sheets(self) -> SensorSheets:
        """The sensors' calibration sheets of the stored rig configuration (``[sensors]``; none if it has
        none); ValueError naming the file if they cannot be read."""
        stored = self.rig_config.get("sensors") if isinstance(self.rig_config, Mapping) else None
        if stored is None:
            return SensorSheets()
        return configuration_from_dict({"sensors": stored}, source=f"{self.path}: rig_config").sensors

    @property
    def software_version(self) -> str:
        return self._root["software_version"]

    @property
    def created(self) -> str:
        """ISO 8601 creation time of the session file."""
        return self._root["created"]

    @property
    def active_run(self) -> RunLog | None:
        """The run being recorded, if any."""
        return self._active

    @property
    def last_commit(self) -> Any:
        """How the last structural change was committed (`rig.session.atomic.CommitStats`)."""
        return self._file.last_commit

    def runs(self) -> list[RunInfo]:
        """All run groups in order (the one being recorded with status ``"running"``)."""
        return list(self._runs)

    def done_plan_indices(self) -> set[int]:
        """Plan indices that must not run again: a run of theirs ended completed, refused or skipped."""
        return {run.plan_index for run in self._runs if run.status in schema.DONE_STATUSES}

    # -- runs ---------------------------------------------------------------------------------------------
    def checked_run_attrs(self, attrs: Mapping[str, Any] | None) -> dict[str, Any]:
        """Extra run attributes as stored; ``None`` values are left out (an attribute cannot hold "none")."""
        out = {}
        for key, value in (attrs or {}).items():
            if not isinstance(key, str) or not key or "/" in key or key in schema.RUN_ATTRS:
                raise SessionError(f"{self.path}: attribute name {key!r} is reserved or invalid; expected a new name "
                                   f"(not one of {list(schema.RUN_ATTRS)})")
            if value is None:
                continue
            try:
                out[key] = layout.attr_value(key, value)
            except ValueError as exc:
                raise SessionError(f"{self.path}: {exc}") from None
        return out

    def begin_run(self, plan_index: int, *, record: str, scale_factor: float, angle_deg: float,
                  commanded: np.ndarray, bodies: Iterable[Mapping[str, Any]], sensors: Sequence[str],
                  attrs: Mapping[str, Any] | None = None) -> RunLog:
        """Add run group ``/runs/<NNNN>`` (status ``"running"``) and start recording into it.

        ``scale_factor``: NaN if there is none (e.g. a run refused before its drive was prepared);
        ``angle_deg``: plate inclination [degrees]; ``commanded`` (N, 7): t [s], surge, sway, heave [m], roll,
        pitch, yaw [rad]; ``bodies``: mappings with body_id, b, h, depth [m], mass [kg], x, y [m] (and optional
        name); ``sensors``: accelerometer names, one ``accel/<sensor>`` dataset each; ``attrs``: extra
        attributes (bool/int/float/str; lists and dicts as JSON text; None values left out)."""
        if self._file.fd < 0:
            raise SessionError(f"{self.path}: the session log is closed")
        if self._active is not None:
            raise SessionError(f"{self.path}: run {self._active.name} is still being recorded; end it first")
        try:
            commanded = np.asarray(commanded, dtype=np.float64)
            if commanded.ndim != 2 or commanded.shape[1] != 7:
                raise ValueError(f"commanded has shape {commanded.shape}; expected (N, 7): t, surge, sway, heave, "
                                 "roll, pitch, yaw")
            body_rows = self._body_rows(bodies)
            sensors = [str(s) for s in sensors]
            for sensor in sensors:
                if not sensor or "/" in sensor or sensor.startswith("."):
                    raise ValueError(f"sensor name {sensor!r}; expected a non-empty name without '/'")
            if len(set(sensors)) != len(sensors):
                raise ValueError(f"sensor names repeat: {sensors}")
            scale = float(scale_factor)
            if math.isinf(scale):
                raise ValueError(f"scale_factor is {scale_factor!r}; expected a number (NaN if unknown)")
            angle = schema.finite(angle_deg, "angle_deg")
            plan = int(plan_index)
            stored_sheets = self.sensor_sheets()
            sheets = {name: sheet for name, sheet in stored_sheets.sheets.items() if name in sensors}
            body_ids = {str(int(body)) for body in body_rows["body_id"]}
            tilt_sheets = {body: sheet for body, sheet in stored_sheets.tilts.items() if body in body_ids}
        except (ValueError, TypeError, KeyError) as exc:
            raise SessionError(f"{self.path}: begin_run: {exc}") from None
        extra = self.checked_run_attrs(attrs)
        number = 1 + max((int(run.name) for run in self._runs if run.name.isdigit()), default=0)
        info = RunInfo(name=schema.run_name(number), plan_index=plan,
                       attempt=1 + sum(run.plan_index == plan for run in self._runs), status=schema.RUNNING,
                       record=str(record), angle_deg=angle, scale_factor=scale, started=schema.iso_now(), ended="")
        with self._file.transaction() as h5:
            layout.create_run(h5["runs"], info.name, plan_index=plan, attempt=info.attempt, record=info.record,
                              scale_factor=scale, angle_deg=angle, started=info.started, commanded=commanded,
                              bodies=body_rows, sensors=sensors, attrs=extra, sheets=sheets,
                              tilt_sheets=tilt_sheets)
        self._runs.append(info)
        failpoints.hit("begin:committed")
        try:
            h5 = _open_swmr(self.path)
            try:
                group = h5["runs"][info.name]
                datasets = {"commanded": group["commanded"], "pose": group["pose"], "events": group["events"],
                            "detections": group["detections"], "faults": group["faults"]}
                datasets["following_error"] = group["following_error"]
                datasets.update({f"accel/{sensor}": group["accel"][sensor] for sensor in sensors})
                datasets.update({f"tilt/{name}": group["tilt"][name] for name in group["tilt"]})
                writer = BlockWriter(h5, datasets, self._flush_interval, group[checksums.TABLE])
            except BaseException:
                h5.close()
                raise
        except Exception as exc:  # the group exists but recording could not start: it was not run
            self.finish_run(info, "interrupted", {"begin_error": str(exc)[:500]})
            raise
        writer.start()
        self._active = RunLog(self, info, sensors, [int(b) for b in body_rows["body_id"]], h5, writer,
                              {name: sheet.range_m_s2 for name, sheet in sheets.items()},
                              {int(body): sheet.range_rad for body, sheet in tilt_sheets.items()})
        return self._active

    @staticmethod
    def _body_rows(bodies: Iterable[Mapping[str, Any]]) -> np.ndarray:
        rows = []
        for body in bodies:
            values = [schema.finite(body[key], f"body {key}") for key in ("b", "h", "depth", "mass", "x", "y")]
            name = schema.fixed_text(str(body.get("name", "")), schema.NAME_LEN)
            cg = [math.nan if body.get(key) is None else float(body[key]) for key in ("b_cg", "h_cg")]  # NaN: middle
            rows.append((int(body["body_id"]), *values, name, *cg))
        return np.array(rows, dtype=schema.BODY)

    def finish_run(self, info: RunInfo, status: str, attrs: Mapping[str, Any]) -> RunInfo:
        """Final attributes of the active run (called by `RunLog.end` after its SWMR file is closed)."""
        ended = schema.iso_now()
        try:
            with self._file.transaction() as h5:
                layout.finish_run(h5["runs"][info.name], status=status, ended=ended, attrs=attrs)
        finally:
            self._active = None  # on failure the file keeps "running": resume marks the run interrupted
        done = replace(info, status=status, ended=ended)
        self._runs = [done if run.name == info.name else run for run in self._runs]
        return done

    def close(self) -> None:
        """End a run still being recorded as ``"interrupted"``, then release the file."""
        try:
            if self._active is not None:
                self._active.end("interrupted", end_note="session log closed while the run was being recorded")
        finally:
            self._file.close()

    def __enter__(self) -> SessionLog:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


__all__ = ["FLUSH_INTERVAL", "MAX_FLUSH_INTERVAL", "SessionLog"]
