"""numba's on-disk cache index, written under a lock: processes that compile one kernel at once keep it right.

numba keeps, per kernel, an index (``<kernel>.nbi``: signature → data file) and one data file of machine code
per signature (``<kernel>.<n>.nbc``). ``IndexDataCacheFile.save`` (``numba/core/caching.py``) reads the index,
takes the first number it does not list, writes the index, then the data, and holds no lock: two processes that
save two signatures of one kernel at once (xdist workers, a study's process pool) can both take ``1``, and the
index can be left naming, for one signature, the other signature's machine code, which every later process then
loads and runs on the wrong argument types (``tests/analysis/test_compiled_index.py`` replays that interleaving).

Here a data file's name is a hash of the kernel's source stamp and the signature's key, so a name never holds
anything else; the data file is written before the index names it; and the index is read, updated and written
under an exclusive ``flock`` of ``<kernel>.nbi.lock`` (kept: removing a lock file races with its next user).
When a kernel's index starts afresh (none yet, or its source changed) the kernel's data files it does not name
are removed, so edits do not pile up machine code. Readers need no lock: numba replaces every file atomically.

The kernels are compiled with :data:`njit` from here (numba's, imported after :class:`LockedIndexDataCacheFile`
is in place).
"""

from __future__ import annotations

import fcntl
import hashlib
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numba
from numba.core import caching


class LockedIndexDataCacheFile(caching.IndexDataCacheFile):
    """numba's index and data files of one kernel, saved under a lock (module docstring)."""

    def save(self, key: Any, data: Any) -> None:
        """Save ``data`` (a compiled signature) under ``key`` (signature, target, bytecode hashes)."""
        digest = hashlib.sha256(repr((self._source_stamp, key)).encode()).digest()
        name = self._data_name(int.from_bytes(digest[:8], "big"))
        with exclusive(self._index_path + ".lock"):
            overloads = self._load_index()
            if not overloads:
                self._remove_data_files(keep=name)
            self._save_data(name, data)
            overloads[key] = name
            self._save_index(overloads)

    def _remove_data_files(self, keep: str) -> None:
        """Remove this kernel's data files but ``keep`` (those of an older source, or of no index)."""
        for path in Path(self._cache_path).glob(self._data_name_pattern.replace("{number:d}", "*")):
            if path.name != keep:
                path.unlink(missing_ok=True)


@contextmanager
def exclusive(path: str | os.PathLike[str]) -> Iterator[None]:
    """Hold an exclusive advisory lock on the file at ``path`` (created if missing) while the block runs."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


# what numba's caches are made with from now on (numba/core/caching.py looks the class up when a kernel is defined)
caching.IndexDataCacheFile = LockedIndexDataCacheFile  # type: ignore[misc]  # replacing numba's class is the point

njit = numba.njit
"""numba's ``njit``: the project's kernels are defined with this one, so that their caches use the lock."""
