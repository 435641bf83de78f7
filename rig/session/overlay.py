"""The file object a session-file transaction opens with h5py (see `rig.session.atomic`).

HDF5 reads and writes through it instead of the file: writes at or beyond ``boundary`` (the end of allocation
when the transaction began: new space no metadata of the file refers to yet) go straight to the file; writes
below it ("in place") are kept in memory per 4 KiB page, and reads see them. After h5py has closed the file,
`Overlay.changed_pages` tells the committer which pages the transaction changes in place.

A write to the file that fails (a full disk: ENOSPC, EFBIG, EDQUOT) is kept in `Overlay.error` and that write and
every later one to the file are skipped, not raised: HDF5 calls this object from C, also while h5py frees its
objects, and an exception there leaves the library in a state that crashed the process (a segmentation fault). The
transaction then refuses to commit (`rig.session.atomic`): nothing the file's metadata refers to has changed.
"""

from __future__ import annotations

import io
import os
from collections.abc import Iterator

from .hdf5props import PAGE


class Overlay(io.RawIOBase):
    """A read-write file object over descriptor ``fd`` for h5py's file-object driver (see the module doc);
    ``boundary``: the file's end of allocation [bytes] when the transaction began."""

    def __init__(self, fd: int, boundary: int) -> None:
        super().__init__()
        self._fd = fd
        self._boundary = boundary
        self._size = os.fstat(fd).st_size
        self._pos = 0
        self._pages: dict[int, bytearray] = {}
        self.start_size = self._size
        """The file's length when the transaction began [bytes]."""
        self.error: OSError | None = None
        """The first write to the file that failed (module docstring); None while all succeeded."""

    # -- file-object protocol used by h5py's driver ------------------------------------------------------
    def readable(self) -> bool:
        return True

    def writable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        base = {os.SEEK_SET: 0, os.SEEK_CUR: self._pos, os.SEEK_END: self._size}[whence]
        self._pos = base + offset
        return self._pos

    def tell(self) -> int:
        return self._pos

    def _disk(self, offset: int, n: int) -> bytes:
        data = os.pread(self._fd, n, offset)
        return data if len(data) == n else data.ljust(n, b"\0")

    def _page(self, index: int) -> bytearray:
        page = self._pages.get(index)
        if page is None:
            page = self._pages[index] = bytearray(self._disk(index * PAGE, PAGE))
        return page

    def _spans(self, n: int) -> Iterator[tuple[int, int, int, int | None]]:
        """The ``n`` bytes from the position in spans ``(done, at, k, page)``: ``k`` bytes at file offset ``at``,
        ``done`` bytes into the request; ``page`` the index of the kept page holding them below the boundary
        (one span per page), None at or beyond it (one span for the rest)."""
        pos, done = self._pos, 0
        while done < n:
            at = pos + done
            if at < self._boundary:
                index, offset = divmod(at, PAGE)
                k = min(PAGE - offset, n - done, self._boundary - at)
                yield done, at, k, index
            else:
                k = n - done
                yield done, at, k, None
            done += k

    def readinto(self, buffer: memoryview | bytearray) -> int:  # type: ignore[override]  # what h5py hands in
        view = memoryview(buffer).cast("B")
        n = len(view)
        for done, at, k, index in self._spans(n):
            page = None if index is None else self._pages.get(index)
            if index is None or page is None:
                view[done : done + k] = self._disk(at, k)
            else:
                offset = at - index * PAGE
                view[done : done + k] = page[offset : offset + k]
        self._pos += n
        return n

    def write(self, data: bytes | memoryview) -> int:  # type: ignore[override]  # what h5py hands in
        view = memoryview(data).cast("B")
        n = len(view)
        for done, at, k, index in self._spans(n):
            if index is None:
                written = 0
                while written < k and self.error is None:
                    try:
                        written += os.pwrite(self._fd, view[done + written : done + k], at + written)
                    except OSError as exc:
                        self.error = exc
            else:
                offset = at - index * PAGE
                self._page(index)[offset : offset + k] = view[done : done + k]
        self._pos += n
        self._size = max(self._size, self._pos)
        return n

    def truncate(self, size: int | None = None) -> int:
        self._size = self._pos if size is None else size
        return self._size

    def flush(self) -> None:
        pass

    # -- commit --------------------------------------------------------------------------------------------
    def changed_pages(self) -> dict[int, tuple[bytes, bytes]]:
        """Pages below the boundary whose kept bytes differ from the file: index → (old, new)."""
        changed = {}
        for index, page in sorted(self._pages.items()):
            old = self._disk(index * PAGE, PAGE)
            if old != page:
                changed[index] = (old, bytes(page))
        return changed

    @property
    def new_size(self) -> int:
        """The file length HDF5 left (its EOA at close) [bytes]."""
        return self._size
