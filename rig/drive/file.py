"""The compensated drive as a file (schema ``shaketable-rig/drive/1``) that ``rig iterate`` writes and a sequence
plays (``drive = "FILE"`` in a ``[[records]]`` entry, ``docs/sequence-files.md``).

HDF5: datasets ``t`` (N,) [s], ``poses``, ``velocities``, ``accelerations`` (N, 6) (the session's ``commanded``
columns and their derivatives); attributes ``schema``, ``record``, ``angle_rad``, ``rate_hz``, ``scale_factor``,
``corner_frequency_hz``, ``record_start``, ``motion`` [s, s], ``components``, ``governing``, ``peaks`` (JSON),
``rig_config`` (JSON, the table model it was iterated on), ``compensation`` (JSON: the iterations' errors, the
session file). Written under a temporary name and linked into place: the name appears with a whole file or not at
all, and an existing file is never replaced.

**Reading it back** checks the drive as a command (``TableModel.check_command``: the displacement envelope, the
tilt, the legs' stroke and speed — what the table enforces on its setpoints). A compensated drive may ask more than
Table IV's acceleration (or velocity) of an axis where the table attenuates (``rig.compensation.iteration``): such
a drive is taken only when its ``compensation`` record shows it played at full level with the plate's achieved
acceleration within Table IV; any other drive is held to all of Table IV as well.
"""

from __future__ import annotations

import json
import math
import os
import secrets
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from analysis.table.model import TableModel
from rig.drive import Drive, DriveRefusedError, Governing

SCHEMA = "shaketable-rig/drive/1"


class DriveFileError(ValueError):
    """A drive file that cannot be written or read; the message names the file and what is wrong."""


def save_drive(path: str | os.PathLike[str], drive: Drive, compensation: dict[str, Any]) -> Path:
    """Write ``drive`` to a new file ``path`` (module docstring); DriveFileError if something exists there."""
    path = Path(path)
    if path.exists() or path.is_symlink():
        raise DriveFileError(f"{path}: already exists; a drive file is never overwritten, choose another name")
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(6)}.writing")
    gov = drive.governing
    try:
        with h5py.File(tmp, "w-") as h5:
            for name in ("t", "poses", "velocities", "accelerations"):
                h5.create_dataset(name, data=np.asarray(getattr(drive, name), dtype=float))
            h5.attrs.update({
                "schema": SCHEMA, "record": drive.record, "angle_rad": drive.angle, "rate_hz": drive.rate,
                "scale_factor": drive.scale_factor, "corner_frequency_hz": drive.corner_frequency,
                "record_start": drive.record_start, "motion": np.array(drive.motion, dtype=float),
                "components": json.dumps(list(drive.components)),
                "governing": json.dumps({"axis": gov.axis, "quantity": gov.quantity, "peak": gov.peak,
                                         "limit": gov.limit, "binding": gov.binding}),
                "peaks": json.dumps(drive.peaks), "rig_config": json.dumps(drive.table.to_dict()),
                "compensation": json.dumps(compensation, allow_nan=False)})
        os.link(tmp, path)
    except FileExistsError:
        raise DriveFileError(f"{path}: already exists; a drive file is never overwritten") from None
    except OSError as exc:
        raise DriveFileError(f"{path}: cannot write the drive file ({exc})") from None
    finally:
        tmp.unlink(missing_ok=True)
    return path


def load_drive(path: str | os.PathLike[str], table: TableModel | None = None, *, angle: float | None = None) -> Drive:
    """The drive in ``path``, checked against ``table`` (default: the model it was iterated on) and, when given, to
    be at tilt ``angle`` [rad]; DriveFileError naming the file and the problem, DriveRefusedError when it leaves
    the table."""
    path = Path(path)
    try:
        with h5py.File(path, "r", locking=False) as h5:
            found = h5.attrs.get("schema")
            if found != SCHEMA:
                raise DriveFileError(f"{path}: schema attribute is {found!r}; expected {SCHEMA!r} (a drive file "
                                     "written by rig iterate)")
            data = {name: np.array(h5[name]) for name in ("t", "poses", "velocities", "accelerations")}
            attrs = {key: h5.attrs[key] for key in h5.attrs}
    except FileNotFoundError:
        raise DriveFileError(f"{path}: no such drive file") from None
    except (OSError, KeyError) as exc:
        raise DriveFileError(f"{path}: unreadable drive file ({exc})") from None
    own = TableModel.from_dict(json.loads(attrs["rig_config"]), source=f"{path}: rig_config")
    table = table or own
    rate = float(attrs["rate_hz"])
    if not math.isclose(rate, table.controller_rate):
        raise DriveFileError(f"{path}: the drive is sampled at {rate:g} Hz, the table plays "
                             f"{table.controller_rate:g} Hz")
    if angle is not None and not math.isclose(float(attrs["angle_rad"]), angle, abs_tol=1e-9):
        raise DriveFileError(f"{path}: the drive was iterated at β = {math.degrees(float(attrs['angle_rad'])):g}°, "
                             f"not {math.degrees(angle):g}°")
    gov = json.loads(attrs["governing"])
    drive = Drive(record=str(attrs["record"]), angle=float(attrs["angle_rad"]), rate=rate, t=data["t"],
                  poses=data["poses"], velocities=data["velocities"], accelerations=data["accelerations"],
                  scale_factor=float(attrs["scale_factor"]), governing=Governing(**gov),
                  corner_frequency=float(attrs["corner_frequency_hz"]), record_start=float(attrs["record_start"]),
                  motion=(float(attrs["motion"][0]), float(attrs["motion"][1])), peaks=json.loads(attrs["peaks"]),
                  highpass_pga_ratio={}, components=tuple(json.loads(attrs["components"])), table=table)
    violation = table.check_command(drive.t, drive.poses, drive.velocities, drive.accelerations)
    if violation is None and not _played_inside_table_iv(json.loads(attrs["compensation"])):
        violation = table.check_trajectory(drive.t, drive.poses, drive.velocities, drive.accelerations)
    if violation is not None:
        raise DriveRefusedError(drive.record, violation)
    return drive


def _played_inside_table_iv(compensation: dict[str, Any]) -> bool:
    """Whether the file's ``compensation`` record shows its drive (the ``best`` play) played at full level with the
    plate's achieved acceleration within Table IV (``peak_to_limit`` ≤ 1)."""
    plays = compensation.get("iterations")
    best = compensation.get("best")
    if not isinstance(plays, list) or not isinstance(best, int) or not 0 <= best < len(plays):
        return False
    play = plays[best]
    return (isinstance(play, dict) and play.get("level_db") == 0.0
            and isinstance(play.get("peak_to_limit"), float) and play["peak_to_limit"] <= 1.0)
