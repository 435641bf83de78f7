"""Crash-atomic changes to the structure of a session file (new run group, a run's final attributes).

HDF5 itself cannot do this: a file open for writing without SWMR is flagged "open for write" in its
superblock until it is closed (a killed writer leaves a file that no h5py mode opens), and HDF5 writes its
changed metadata blocks in no particular order, so a kill part-way leaves a mix of old and new blocks.

`SessionFile.transaction` instead opens the file through h5py's Python file-object driver on an
`rig.session.overlay.Overlay`:

* writes at or beyond the file's end of allocation (EOA, from the superblock) go straight to the file: they
  are new space that no metadata of the current file refers to, so until the commit they are invisible;
* writes below the EOA ("in place") are kept in memory, per 4 KiB page; reads see them.

When the h5py file has been closed, the commit compares the kept pages with the file. HDF5 rewrites the
superblock (and the time stamps of the superblock extension) on every close, but with the file's paged
aggregation and the compact link/attribute storage of `rig.session.hdf5props`, adding a run group or
finishing one changes at most *one* other page (checked on every commit, and tested over 130 runs):

1. new space is made durable (``fdatasync``) and the file is extended to the new EOA;
2. if the EOA grew, page 0's change (superblock EOA and checksum, superblock-extension time stamps) is written
   first: the old structure with a larger EOA is a valid file; if it shrank, it is written last;
3. the one changed page is written with a single ``pwrite`` inside that page — the kernel copies a page into
   the page cache whole once it has started, so ``kill -9`` sees it all or not at all.

Every state in between is the old file or the new one. Should a transaction change more than one page (two
run groups at once, or an HDF5 library where the compact-storage settings could not be applied),
`SessionFile._shadow_commit` writes a complete new copy of the file beside it and renames it over the original
(atomic too; costs a copy of the file). A transaction whose body raises leaves the file as it was.

Power loss (beyond ``kill -9``): the ``fdatasync`` calls order new space before the page that links it; a page
write is then as atomic as the disk's 4 KiB writes. Crash points for the tests: `rig.session.failpoints`.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import h5py

from . import failpoints, superblock
from .errors import SessionError
from .hdf5props import LIBVER, PAGE
from .locks import lock_fd
from .overlay import Overlay


@dataclass
class CommitStats:
    """What a commit did: ``method`` is ``"none"``, ``"pages"`` (in place) or ``"shadow"`` (copy + rename)."""

    method: str = "none"
    pages: int = 0
    bytes_in_place: int = 0
    seconds: float = 0.0


def _span(old: bytes, new: bytes) -> tuple[int, int]:
    """First and one-past-last differing byte."""
    first = next(i for i in range(len(new)) if old[i] != new[i])
    last = next(i for i in range(len(new) - 1, -1, -1) if old[i] != new[i])
    return first, last + 1


def _pwrite_all(fd: int, data: bytes, offset: int) -> None:
    view, done = memoryview(data), 0
    while done < len(data):
        done += os.pwrite(fd, view[done:], offset + done)


class SessionFile:
    """The writer's locked descriptor of a session file and the transactions on it."""

    def __init__(self, path: Path, fd: int) -> None:
        self.path = path
        self.fd = fd
        self.last_commit = CommitStats()

    def close(self) -> None:
        """Release the locks (by closing the descriptor)."""
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1

    def superblock(self) -> superblock.Superblock:
        return superblock.read(self.fd, self.path)

    def clear_open_flags(self) -> bool:
        """After a writer was killed: clear the superblock's "open for write" flags and make the EOA cover every
        byte of the file (a SWMR writer may have written past the EOA it last stored). One write in page 0.
        Returns whether anything had to be done."""
        sb = self.superblock()
        size = os.fstat(self.fd).st_size
        eoa = max(sb.eoa, -(-size // PAGE) * PAGE)
        if sb.flags == 0 and eoa == sb.eoa and size >= eoa:
            return False
        if size < eoa:
            os.ftruncate(self.fd, eoa)
        os.fdatasync(self.fd)
        _pwrite_all(self.fd, sb.patched(flags=0, eoa=eoa), 0)
        os.fdatasync(self.fd)
        failpoints.hit("resume:flags-cleared")
        return True

    @contextlib.contextmanager
    def transaction(self) -> Iterator[h5py.File]:
        """An h5py file on which changes are committed atomically when the block ends without an exception."""
        sb = self.superblock()
        if sb.flags:
            raise SessionError(f"{self.path}: the file is still marked open for writing (flags {sb.flags:#x}); "
                               "resume the session first")
        overlay = Overlay(self.fd, sb.eoa)
        h5 = h5py.File(overlay, "r+", libver=LIBVER, locking=False)
        try:
            yield h5
        except BaseException:
            with contextlib.suppress(Exception):
                h5.close()
            self._refuse_failed(overlay)
            raise
        h5.close()
        self._refuse_failed(overlay)
        failpoints.hit("commit:closed")
        self.last_commit = self._commit(overlay)

    def _refuse_failed(self, overlay: Overlay) -> None:
        """Raise (nothing committed) if a write of the transaction failed; the space it took is given back."""
        if overlay.error is None:
            return
        with contextlib.suppress(OSError):
            os.ftruncate(self.fd, overlay.start_size)
        raise SessionError(f"{self.path}: cannot write ({overlay.error}); nothing of this change was committed, "
                           "the file is as it was") from overlay.error

    def _commit(self, overlay: Overlay) -> CommitStats:
        t0 = time.perf_counter()
        changed = overlay.changed_pages()
        size = os.fstat(self.fd).st_size
        if not changed and overlay.new_size <= size:
            return CommitStats("none", seconds=time.perf_counter() - t0)
        meaningful = [i for i, (old, new) in changed.items()
                      if not (i == 0 and superblock.superblock_only_change(old, new))]
        if len(meaningful) > 1 or failpoints.FORCE_SHADOW:
            return self._shadow_commit(changed, overlay.new_size, t0)
        if overlay.new_size > size:
            os.ftruncate(self.fd, overlay.new_size)
        os.fdatasync(self.fd)  # new space durable before anything refers to it (power loss, not only kill -9)
        failpoints.hit("commit:new-space")
        order = list(meaningful)
        if 0 in changed and 0 not in meaningful:
            old_eoa = superblock.parse(changed[0][0]).eoa
            new_eoa = superblock.parse(changed[0][1]).eoa
            order = [0, *order] if new_eoa >= old_eoa else [*order, 0]
        written = 0
        for index in order:
            old, new = changed[index]
            first, end = _span(old, new)
            _pwrite_all(self.fd, new[first:end], index * PAGE + first)  # inside one page: all or nothing
            written += end - first
            failpoints.hit("commit:page")
        os.fdatasync(self.fd)
        return CommitStats("pages", len(order), written, time.perf_counter() - t0)

    def _shadow_commit(self, changed: dict[int, tuple[bytes, bytes]], new_size: int, t0: float) -> CommitStats:
        """Copy the file, apply the change to the copy, rename it over the original (atomic)."""
        tmp = self.path.with_name(f".{self.path.name}.{secrets.token_hex(6)}.shadow")
        mode = os.fstat(self.fd).st_mode & 0o777
        tfd = os.open(tmp, os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, mode)
        try:
            size = os.fstat(self.fd).st_size
            offset = 0
            while offset < size:
                try:
                    n = os.copy_file_range(self.fd, tfd, size - offset, offset, offset)
                except OSError:
                    n = 0
                if n <= 0:  # no copy_file_range here: plain copy of the rest
                    while offset < size:
                        chunk = os.pread(self.fd, min(1 << 22, size - offset), offset)
                        _pwrite_all(tfd, chunk, offset)
                        offset += len(chunk)
                    break
                offset += n
            for index, (_old, new) in changed.items():
                _pwrite_all(tfd, new, index * PAGE)
            os.ftruncate(tfd, max(new_size, 0))
            os.fsync(tfd)
            lock_fd(tfd, self.path)
            failpoints.hit("shadow:before-rename")
            os.replace(tmp, self.path)
        except BaseException:
            os.close(tfd)
            with contextlib.suppress(OSError):
                tmp.unlink()
            raise
        failpoints.hit("shadow:renamed")
        fsync_dir(self.path.parent)
        os.close(self.fd)
        self.fd = tfd
        return CommitStats("shadow", len(changed), size, time.perf_counter() - t0)


def fsync_dir(directory: Path) -> None:
    """fsync a directory (a new or renamed entry in it survives a power loss), ignoring file systems that refuse."""
    with contextlib.suppress(OSError):
        dfd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)


def remove_stale_temporaries(path: Path) -> list[Path]:
    """Delete leftovers of a killed create or shadow commit of this session file (``.<name>.*.shadow|creating``)."""
    removed = []
    for pattern in (f".{path.name}.*.shadow", f".{path.name}.*.creating"):
        for tmp in path.parent.glob(pattern):
            with contextlib.suppress(OSError):
                tmp.unlink()
                removed.append(tmp)
    return removed
