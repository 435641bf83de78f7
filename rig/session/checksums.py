"""CRC-32 checksums of a run's samples, one per written block, in the run's ``checksums`` table.

HDF5's Fletcher32 filter is not used: it checksums a whole chunk, and the session writer rewrites the last chunk of
each dataset in place at every flush, so a ``kill -9`` mid-write would leave a chunk whose checksum fails and make
its earlier rows unreadable, and live SWMR readers could meet checksum errors. Instead each block of rows the
writer puts on disk gets one row of ``/runs/<NNNN>/checksums`` (`CHECKSUM`): the dataset's name inside the run
(``accel/plate``), the block's first row, its row count and the CRC-32 (``zlib.crc32``) of its bytes as stored
(rows in the dataset's dtype, C order, little-endian).

A block's row is written by the *next* flush of the writer (or its last one, at the run's end), after the flush
that put the block's rows on disk has completed. So a file left by a killed writer never holds a checksum row
whose rows are not on disk; rows written after the last checksummed block are *unverified* (neither verified nor
damaged). `verify` checks a run group: rows that do not match their checksum, a checksum row whose rows are
missing from a run that is not being recorded, or a table whose blocks do not follow each other is damage
(`DamagedFileError` naming run, dataset and rows). Runs written before the table existed are "not checksummed".
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from . import schema
from .errors import DamagedFileError

#: The table's name in a run group.
TABLE = "checksums"
#: Longest dataset name in the table [bytes] (``tilt/<body_id>``, ``accel/<sensor>``).
DATASET_LEN = 64
CHECKSUM = np.dtype([("dataset", h5py.string_dtype("utf-8", DATASET_LEN)), ("first_row", "<i8"), ("rows", "<i8"),
                     ("crc32", "<u4")])
#: The unit of each field of `CHECKSUM` (the ``units`` attribute): a name, two row counts, a checksum.
CHECKSUM_UNITS = (schema.NOT_A_QUANTITY, "1", "1", schema.NOT_A_QUANTITY)

#: `RunChecksums.state` values.
VERIFIED, NOT_CHECKSUMMED = "verified", "not checksummed"


def crc32(rows: np.ndarray) -> int:
    """CRC-32 of ``rows``' bytes in C order (the dtype as stored in the file)."""
    return zlib.crc32(np.ascontiguousarray(rows).data)


def entry(dataset: str, first_row: int, rows: np.ndarray) -> tuple[bytes, int, int, int]:
    """One `CHECKSUM` row for ``rows`` written to ``dataset`` from row ``first_row``."""
    return schema.fixed_text(dataset, DATASET_LEN), first_row, len(rows), crc32(rows)


def create_table(group: h5py.Group, initial: Mapping[str, np.ndarray]) -> h5py.Dataset:
    """The run's empty-or-initial ``checksums`` table (chunked, unlimited, appended by the writer), with one row
    per non-empty dataset of ``initial`` (name inside the run → the rows it was created with)."""
    rows = np.array([entry(name, 0, data) for name, data in initial.items() if len(data)], dtype=CHECKSUM)
    return group.create_dataset(TABLE, data=rows, maxshape=(None,), chunks=(schema.TABLE_CHUNK,), dtype=CHECKSUM,
                                track_times=False)


@dataclass
class RunChecksums:
    """What `verify` found in one run: ``state`` `VERIFIED` or `NOT_CHECKSUMMED`; ``verified_rows`` per dataset;
    ``unverified`` per dataset: the rows [first, end) after its last checksummed block (a killed writer's last
    flush, or a run still being recorded)."""

    state: str
    verified_rows: dict[str, int] = field(default_factory=dict)
    unverified: dict[str, tuple[int, int]] = field(default_factory=dict)


def _damaged(path: Path, run: str, dataset: str, first: int, end: int, what: str) -> DamagedFileError:
    return DamagedFileError(path, f"run {run} dataset {dataset} rows {first}–{end - 1}: {what}")


def read_table(group: h5py.Group) -> dict[str, list[tuple[int, int, int]]] | None:
    """The run's checksum table as {dataset: [(first_row, rows, crc32), …]}, None for a run without one (written
    before checksums). Read it before the datasets: a live writer then only adds rows to what is read after."""
    if TABLE not in group:
        return None
    blocks: dict[str, list[tuple[int, int, int]]] = {}
    for row in group[TABLE][()]:
        name = bytes(row["dataset"]).decode("utf-8", "replace")
        blocks.setdefault(name, []).append((int(row["first_row"]), int(row["rows"]), int(row["crc32"])))
    return blocks


def verify(path: Path, run: str, blocks: Mapping[str, list[tuple[int, int, int]]] | None,
           arrays: Mapping[str, np.ndarray], *, recording: bool) -> RunChecksums:
    """Check the datasets of run ``run`` (``arrays``: name inside the run → its rows as read, after ``blocks``:
    `read_table`) against their checksums. ``recording``: the run is still being recorded (status ``running``):
    a checksum row may then be newer than what this reader saw of its dataset. `DamagedFileError` as in the module
    docstring."""
    if blocks is None:
        return RunChecksums(NOT_CHECKSUMMED)
    for name, listed in blocks.items():
        if name not in arrays:
            first, count, _ = listed[0]
            raise _damaged(path, run, name, first, first + count, "the checksum table names a dataset the run has not")
    result = RunChecksums(VERIFIED)
    for name, data in arrays.items():
        length = len(data)
        done = 0
        for first, count, expected in sorted(blocks.get(name, [])):
            end = first + count
            if first != done or count <= 0:
                raise _damaged(path, run, name, first, end, f"checksum table block out of sequence (expected a block "
                                                             f"from row {done})")
            if end > length:
                if recording:
                    break
                raise _damaged(path, run, name, first, end, f"missing: the dataset has {length} rows")
            found = crc32(data[first:end])
            if found != expected:
                raise _damaged(path, run, name, first, end, f"checksum 0x{found:08x}, expected 0x{expected:08x} "
                                                            "(the samples changed after they were written)")
            done = end
        result.verified_rows[name] = done
        if done < length:
            result.unverified[name] = (done, length)
    return result


def notes(found: Mapping[str, Any] | None) -> list[str]:
    """What an operator is told about a run's checksums as `rig.session.read_session` gives them (``run["checksums"]``):
    nothing when every row was verified; "not checksummed" for a run written before checksums; each dataset's
    unverified rows."""
    if not found:
        return []
    if found.get("state") == NOT_CHECKSUMMED:
        return ["samples not checksummed (the run was written before checksums existed)"]
    unverified = found.get("unverified") or {}
    return [f"{name} rows {first}–{end - 1} unverified (after the last checksummed block: the writer stopped "
            "before checksumming them)" for name, (first, end) in unverified.items()]
