"""The writer's hold on a session file: one open descriptor with an exclusive lock.

* An exclusive *open-file-description* lock (``F_OFD_SETLK``) makes a second `SessionLog` on the same file
  fail at once (another process, or the same one). OFD locks belong to this descriptor only, so HDF5 opening
  and closing the file in this process does not drop them (classic POSIX ``lockf`` locks would be), and on
  Linux they are independent of ``flock``.
* A shared ``flock`` makes any HDF5 program that opens the file *for writing* with HDF5's default file
  locking fail ("unable to lock file") while the session is being written; readers, which take a shared
  ``flock`` or none, are not hindered. (Skipped when ``HDF5_USE_FILE_LOCKING`` forces HDF5 locking on for this
  process: HDF5's own exclusive ``flock`` would then collide with it.)

Both go when the process ends, however it ends, so a killed writer never leaves a stale lock.
"""

from __future__ import annotations

import errno
import fcntl
import os
import struct
from pathlib import Path

from .errors import SessionError

_FLOCK = struct.Struct("hhqqi4x")  # struct flock on Linux x86-64/aarch64: type, whence, start, len, pid


def _hdf5_locking_forced() -> bool:
    value = os.environ.get("HDF5_USE_FILE_LOCKING", "").strip().upper()
    return value not in ("", "FALSE", "0")


def lock_fd(fd: int, path: Path) -> None:
    """Take the writer's locks on ``fd``; `SessionError` naming the file if another writer holds them."""
    try:
        fcntl.fcntl(fd, fcntl.F_OFD_SETLK, _FLOCK.pack(fcntl.F_WRLCK, os.SEEK_SET, 0, 0, 0))
    except OSError as exc:
        if exc.errno in (errno.EAGAIN, errno.EACCES):
            raise SessionError(f"{path}: the session file is being written by another process (or another "
                               "SessionLog in this one); expected no other writer") from None
        raise SessionError(f"{path}: cannot lock the session file ({exc.strerror})") from None
    if not _hdf5_locking_forced():
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno in (errno.EAGAIN, errno.EWOULDBLOCK):
                raise SessionError(f"{path}: another program has the file open for writing with HDF5; expected "
                                   "no other writer") from None
            # a file system without flock: the OFD lock still guards against a second session log


def open_locked(path: Path) -> int:
    """Open ``path`` read-write and take the writer's locks; returns the descriptor."""
    try:
        fd = os.open(path, os.O_RDWR | os.O_CLOEXEC)
    except FileNotFoundError:
        raise SessionError(f"{path}: no such session file") from None
    except OSError as exc:
        raise SessionError(f"{path}: cannot open the session file for writing ({exc.strerror})") from None
    try:
        lock_fd(fd, path)
    except BaseException:
        os.close(fd)
        raise
    return fd


def writer_holds(path: Path) -> bool:
    """True if a session log (in any process, this one included) holds the writer's lock on ``path`` now.

    Asks the kernel which lock a writer's request would meet (``F_OFD_GETLK``) without taking one, on a
    read-only descriptor; a killed writer's lock is gone with its process, so a crashed file answers False."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
    except FileNotFoundError:
        raise SessionError(f"{path}: no such session file") from None
    except OSError as exc:
        raise SessionError(f"{path}: cannot open the session file ({exc.strerror})") from None
    try:
        answer = fcntl.fcntl(fd, fcntl.F_OFD_GETLK, _FLOCK.pack(fcntl.F_WRLCK, os.SEEK_SET, 0, 0, 0))
    finally:
        os.close(fd)
    return _FLOCK.unpack(answer)[0] != fcntl.F_UNLCK
