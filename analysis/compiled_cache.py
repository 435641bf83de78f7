"""Where numba keeps the compiled kernels: a directory keyed by the analysis sources.

numba's own cache invalidation looks only at the file that defines a kernel, not at the functions
it inlines from other modules (``equations``, ``hermite``), so an edit there could leave a stale
kernel in use. Keying the cache directory by a hash of every module of this package makes any edit
start from a fresh cache. ``NUMBA_CACHE_DIR`` set by the user wins.

numba itself is not imported here (it takes half a second): if it is not loaded yet, the directory goes into
``NUMBA_CACHE_DIR``, which numba reads when it is first imported (and child processes inherit, with the same
sources); if it is, into ``numba.config.CACHE_DIR``.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import sys
import time
from pathlib import Path

KEEP_DAYS = 30


def configure() -> Path | None:
    """Point numba's cache at ``$XDG_CACHE_HOME/shaketable-rig/numba/<hash>`` (before any kernel is
    defined); prune other versions unused for ``KEEP_DAYS``. Returns the directory, or None when
    the user chose one."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    here = Path(__file__).parent
    digest = hashlib.sha256()
    for src in sorted(here.glob("*.py")):
        digest.update(src.name.encode() + b"\0" + src.read_bytes())
    root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "shaketable-rig" / "numba"
    target = root / digest.hexdigest()[:16]
    try:
        target.mkdir(parents=True, exist_ok=True)
        os.utime(target)
        for other in root.iterdir():
            if other != target and time.time() - other.stat().st_mtime > KEEP_DAYS * 86400:
                shutil.rmtree(other, ignore_errors=True)
    except OSError:
        return None  # read-only home: numba falls back to its own locations
    numba = sys.modules.get("numba")
    if numba is not None:
        numba.config.CACHE_DIR = str(target)
    else:
        os.environ["NUMBA_CACHE_DIR"] = str(target)
    return target
