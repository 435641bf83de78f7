"""The project's own HDF5 record file (``.h5``): one `GroundMotion`, schema ``shaketable-rig/record/1``.

Layout (readable with any HDF5 tool; h5py example: ``h5py.File(path)["acc_h"][()]``):

* root attributes: ``schema = "shaketable-rig/record/1"``, ``name`` (text), ``dt`` (float64, s),
  ``units = "g"``, ``provenance`` (JSON text of an object: source files, checksums, units, …);
* datasets ``acc_h`` (float64, g, 1-D: first horizontal component) and, when the record has them,
  ``acc_h2`` (second horizontal) and ``acc_v`` (vertical), of the same length; each with ``units = "g"``;
* the component of a one-channel record (horizontal, vertical or unknown) is the one its source file gave,
  in ``provenance["component"]`` (`component`); an unknown one is read with a `RecordWarning`;
* a 512-byte HDF5 user block at the start of the file (HDF5 tools skip it) holding the ASCII text
  ``shaketable-rig/record/1\\nsha256 <64 hex digits>\\n`` padded with NUL bytes: the SHA-256 of every byte
  after the user block. The reader checks it before HDF5 parses anything, because the HDF5 library may
  hang or crash on a damaged file. A file changed after it was written (even by an HDF5 tool) is
  therefore refused.

`write_record` writes a temporary file in the target's directory and moves it into place, so that a
reader sees the old file or the complete new one, never a partial file; it never overwrites an existing
file unless asked to.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import secrets
from pathlib import Path
from typing import Any

import numpy as np

from .component import UNKNOWN, kind_of_provenance, unknown_component
from .motion import GroundMotion, RecordError
from .source import dt_problem, given_dt, located, matching_dt, matching_unit, read_record_bytes
from .units import given_unit

SCHEMA = "shaketable-rig/record/1"
#: Size of the HDF5 user block that carries the checksum [bytes].
USERBLOCK = 512
CHANNELS = ("acc_h", "acc_h2", "acc_v")

_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_EXPECTED = f"a shaketable-rig record file (schema {SCHEMA}) written by `rig records import`"


def _userblock(digest: str) -> bytes:
    """The user block: schema line, checksum line, NUL padding to `USERBLOCK` bytes."""
    return f"{SCHEMA}\nsha256 {digest}\n".encode("ascii").ljust(USERBLOCK, b"\0")


def _provenance_json(motion: GroundMotion) -> str:
    """The motion's provenance as JSON text (finite numbers only)."""
    try:
        return json.dumps(motion.provenance, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise RecordError(f"record {motion.name!r}: provenance is not JSON-serialisable ({exc})") from None


def _write_contents(h5: Any, motion: GroundMotion, provenance: str) -> None:
    """Attributes and datasets of a record file (see the module docstring) into an open h5py file."""
    h5.attrs["schema"] = SCHEMA
    h5.attrs["name"] = motion.name
    h5.attrs["dt"] = np.float64(motion.dt)
    h5.attrs["units"] = "g"
    h5.attrs["provenance"] = provenance
    for channel in CHANNELS:
        values = getattr(motion, channel)
        if values is not None:
            dataset = h5.create_dataset(channel, data=np.asarray(values, dtype="<f8"))
            dataset.attrs["units"] = "g"


def _seal(tmp: Path) -> None:
    """Write the checksum user block of a closed record file and flush it to disk."""
    with tmp.open("r+b") as f:
        f.seek(USERBLOCK)
        digest = hashlib.sha256(f.read()).hexdigest()
        f.seek(0)
        f.write(_userblock(digest))
        f.flush()
        os.fsync(f.fileno())


def _publish(tmp: Path, path: Path, replace: bool) -> None:
    """Move the finished ``tmp`` to ``path``: atomically, and without replacing a file unless ``replace``.

    After a hard link the temporary name is still there; the caller removes it.
    """
    if replace:
        os.replace(tmp, path)
        return
    try:
        os.link(tmp, path)  # fails if path exists, even if it appeared since the first check
    except FileExistsError:
        raise located(path, None, "already exists; expected a new file name (or replace it)") from None
    except OSError:  # a file system without hard links: check, then move
        if path.exists():
            raise located(path, None, "already exists; expected a new file name (or replace it)") from None
        os.replace(tmp, path)


def write_record(motion: GroundMotion, path: str | Path, *, replace: bool = False) -> Path:
    """Write ``motion`` to ``path`` as a record file; never a partial file, never over a file unless ``replace``.

    Returns the path written. Raises `RecordError` if ``path`` exists (and not ``replace``), if the
    provenance is not JSON-serialisable or if the file cannot be written.
    """
    import h5py

    path = Path(path)
    if not replace and path.exists():
        raise located(path, None, "already exists; expected a new file name (or replace it)")
    provenance = _provenance_json(motion)
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(8)}.tmp")
    try:
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))  # mode as for any new file
    except OSError as exc:
        raise located(path, None, f"cannot write ({exc.strerror or exc})") from None
    try:
        with h5py.File(tmp, "w", userblock_size=USERBLOCK) as h5:
            _write_contents(h5, motion, provenance)
        _seal(tmp)
        _publish(tmp, path, replace)
    except OSError as exc:
        raise located(path, None, f"cannot write ({exc.strerror or exc})") from None
    finally:
        tmp.unlink(missing_ok=True)
    return path


def _checked_bytes(path: Path) -> tuple[bytes, str]:
    """The file's bytes and SHA-256, after checking the user block's schema and checksum."""
    raw = read_record_bytes(path, "a record file")
    head = f"{SCHEMA}\nsha256 ".encode("ascii")  # then 64 hex digits, as `_userblock` writes them
    if raw[: len(head)] != head or len(raw) < USERBLOCK + len(_HDF5_SIGNATURE):
        raise located(path, None, f"no '{SCHEMA}' user block at byte 0; expected {_EXPECTED}")
    stored = raw[len(head) : len(head) + 64].decode("ascii", "replace")
    if hashlib.sha256(raw[USERBLOCK:]).hexdigest() != stored:
        raise located(
            path, None, "the checksum in the user block does not match the file (changed or damaged since it "
            f"was written); expected {_EXPECTED}",
        )
    if raw[USERBLOCK : USERBLOCK + len(_HDF5_SIGNATURE)] != _HDF5_SIGNATURE:
        raise located(path, None, f"no HDF5 signature after the user block; expected {_EXPECTED}")
    return raw, hashlib.sha256(raw).hexdigest()


def _text(path: Path, h5: Any, key: str) -> str:
    """A text attribute of the root group."""
    if key not in h5.attrs:
        raise located(path, None, f"root attribute {key!r} is missing; expected {_EXPECTED}")
    value = h5.attrs[key]
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    if not isinstance(value, str):
        raise located(path, None, f"root attribute {key!r} is not text; expected {_EXPECTED}")
    return value


def _channel(path: Path, h5: Any, key: str) -> np.ndarray | None:
    """A 1-D float acceleration dataset [g], or None if absent."""
    if key not in h5:
        return None
    node = h5[key]
    if not hasattr(node, "dtype") or node.ndim != 1 or node.dtype.kind != "f":
        raise located(path, None, f"{key!r} is not a 1-D float dataset; expected acceleration samples [g]")
    return np.asarray(node[()], dtype=np.float64)


def _reject_constant(text: str) -> float:
    raise ValueError(f"{text} is not a finite number")


def read_h5(path: str | Path, *, dt: float | None = None, units: str | None = None) -> GroundMotion:
    """Read a record file written by `write_record`; a given ``dt`` [s] or ``units`` must match the file's.

    The motion's provenance is the stored one plus ``stored_in``: this file's path, schema and SHA-256.
    """
    import h5py

    path = Path(path)
    dt, units = given_dt(dt), given_unit(units)
    raw, sha = _checked_bytes(path)
    try:
        with h5py.File(io.BytesIO(raw), "r") as h5:
            schema = _text(path, h5, "schema")
            if schema != SCHEMA:
                raise located(path, None, f"schema is {schema!r}; expected {SCHEMA!r}")
            name = _text(path, h5, "name")
            stored_units = _text(path, h5, "units")
            if stored_units != "g":
                raise located(path, None, f"units is {stored_units!r}; expected 'g'")
            file_dt = h5.attrs.get("dt")
            if not isinstance(file_dt, float | np.floating) or dt_problem(float(file_dt)):
                raise located(
                    path, None, f"root attribute 'dt' is {file_dt!r}; expected a float64 time step [s] "
                    f"({dt_problem(float(file_dt)) if isinstance(file_dt, float | np.floating) else 'not a float'})",
                )
            provenance = json.loads(_text(path, h5, "provenance"), parse_constant=_reject_constant)
            if not isinstance(provenance, dict):
                raise located(path, None, "root attribute 'provenance' is not a JSON object; expected one")
            channels = {key: _channel(path, h5, key) for key in CHANNELS}
    except RecordError:
        raise
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise located(path, None, f"unreadable record content ({exc}); expected {_EXPECTED}") from None
    if channels["acc_h"] is None:
        raise located(path, None, f"dataset 'acc_h' is missing; expected {_EXPECTED}")
    matching_unit(path, None, "g", units)
    matching_dt(path, None, float(file_dt), dt)
    provenance["stored_in"] = {"path": str(path.resolve()), "schema": SCHEMA, "file_sha256": sha}
    if channels["acc_h2"] is None and channels["acc_v"] is None and kind_of_provenance(provenance) == UNKNOWN:
        entry = provenance.get("component")
        said = entry.get("said_by") if isinstance(entry, dict) else None
        provenance["component"] = unknown_component(
            path, None, f"its source file did not say ({said})" if said else "its provenance names no component"
        )
    try:
        return GroundMotion(
            name=name, dt=float(file_dt), acc_h=channels["acc_h"], acc_h2=channels["acc_h2"],
            acc_v=channels["acc_v"], provenance=provenance,
        )
    except RecordError as exc:
        raise located(path, None, f"{exc}; expected {_EXPECTED}") from None
