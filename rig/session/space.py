"""Room for a run on the session file's file system: what a run needs, checked before it begins.

A run appends rows to its datasets while the table moves; a write that fails for want of space mid-run would cut
the record. So before a run begins the orchestrator asks :func:`check_room` for what :func:`run_needs` estimates,
from the drive's duration and what the rig logs per second (float64 rows: accelerometers ``(t, x, y, z)`` at up to
:data:`ACCEL_RATE_BOUND` each, body tilts ``(t, angle)`` at up to :data:`TILT_RATE_BOUND` each, the achieved pose
``(t, 6 pose)`` and the legs' following errors ``(t, 6 legs)`` at up to :data:`STATUS_RATE_BOUND`, and the
commanded drive ``(t, 6 pose)`` once), doubled for HDF5's chunk and metadata overhead, plus :data:`RESERVE_BYTES`
for the run's groups, events and its end.
"""

from __future__ import annotations

import errno
import math
import os
import shutil
from pathlib import Path

from .errors import SessionError

ACCEL_RATE_BOUND = 2000.0
"""Accelerometer samples per second per sensor assumed [Hz] (the rig's sensors give 1 kHz)."""

TILT_RATE_BOUND = 400.0
"""Body-tilt samples per second per body assumed [Hz] (the emulator's give 200 Hz)."""

STATUS_RATE_BOUND = 1000.0
"""Controller statuses per second assumed [Hz] (at most one a controller tick)."""

LINGER_S = 5.0
"""Seconds recorded beyond the drive (the lingering after its end, the stop) assumed [s]."""

OVERHEAD = 2.0
"""Factor for HDF5's chunk padding and metadata."""

RESERVE_BYTES = 16 << 20
"""Bytes kept free beyond the samples: the run's groups, attributes, events, its end, a recovery [bytes]."""

RECOVER_NEEDS = 4 << 20
"""Bytes free that ``rig sessions recover`` asks for before it changes anything (its transaction rewrites a few
metadata pages and may grow the file by as much) [bytes]."""

_ROW = 8  # float64 [bytes]

DISK_FULL_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG})
"""The errors of a write that found no room: no space, quota exceeded, file size limit."""


class DiskFullError(SessionError):
    """No room on the session file's file system; the message starts with ``disk full:`` and says how much."""


def run_needs(duration_s: float, commanded_rows: int, sensors: int, bodies: int) -> int:
    """Bytes a run of a drive ``duration_s`` [s] long with ``commanded_rows`` setpoints, ``sensors`` accelerometers
    and ``bodies`` bodies may write (module docstring)."""
    seconds = duration_s + LINGER_S
    per_second = (sensors * ACCEL_RATE_BOUND * 4 + bodies * TILT_RATE_BOUND * 2 + STATUS_RATE_BOUND * 14) * _ROW
    samples = seconds * per_second + commanded_rows * 7 * _ROW
    return math.ceil(samples * OVERHEAD) + RESERVE_BYTES


def free_bytes(path: str | os.PathLike[str]) -> int:
    """Bytes free to this process on the file system of ``path`` (a file, or the directory it would be in)."""
    where = Path(path)
    while not where.exists() and where != where.parent:
        where = where.parent
    return shutil.disk_usage(where).free


def check_room(path: str | os.PathLike[str], needed: int, what: str) -> None:
    """Raise :class:`DiskFullError` unless the file system of ``path`` has ``needed`` bytes free for ``what``."""
    free = free_bytes(path)
    if free < needed:
        raise DiskFullError(f"disk full: {path}: {what} needs about {_mib(needed)} free, the file system has "
                            f"{_mib(free)}; nothing was written: free some space and try again")


def is_disk_full(exc: BaseException) -> bool:
    """Whether ``exc`` (or what caused it) is a write that found no room (:data:`DISK_FULL_ERRNOS`)."""
    seen: set[int] = set()
    link: BaseException | None = exc
    while link is not None and id(link) not in seen:
        seen.add(id(link))
        if isinstance(link, DiskFullError) or (isinstance(link, OSError) and link.errno in DISK_FULL_ERRNOS):
            return True
        text = str(link)
        if any(f"[Errno {n}]" in text or f"errno = {n}," in text for n in DISK_FULL_ERRNOS):
            return True  # h5py re-raises the C library's error as text
        link = link.__cause__ or link.__context__
    return False


def _mib(n: int) -> str:
    return f"{n / (1 << 20):.1f} MiB"
