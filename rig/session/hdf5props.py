"""HDF5 property lists and library settings that the session file relies on.

* ``LIBVER``: format bounds. The low bound ``v110`` is what SWMR needs (superblock version 3); the high bound
  ``v114`` keeps the file readable by HDF5 1.10–1.14 (h5py wheels of the last years) as well as HDF5 2.x.
* Paged file-space aggregation (``fs_strategy="page"``, 4 KiB pages): HDF5 then never places a metadata block
  smaller than a page across a page boundary, so each in-place metadata rewrite is one write inside one page.
* Readers bound HDF5's retries of a metadata block whose checksum fails (``H5Pset_metadata_read_attempts``):
  a SWMR reader retries 100 times by default, sleeping 2^k ns before attempt k, so a damaged block (a truncated
  or overwritten file) holds it inside HDF5 for ever, where Ctrl-C cannot reach it. `READ_ATTEMPTS` (20: about
  1 ms of sleeps in all) ends it at once; a reader racing the writer retries in Python instead
  (`rig.session.reader`), where each try is short and can be interrupted.
* Link and attribute storage of the groups the log changes after creation is kept *compact* (messages in the
  object header, no fractal heap/B-tree), so that adding a run to ``/runs`` or changing a run's attributes
  rewrites one object-header chunk and nothing else. h5py does not expose the link settings
  (``H5Pset_link_phase_change``, ``H5Pset_est_link_info``); they are called through ``ctypes`` on the HDF5
  library h5py has loaded. Without it the defaults apply and the log stays correct, only slower (see
  `rig.session.atomic`).
"""

from __future__ import annotations

import ctypes
import functools
from pathlib import Path
from typing import Any

import h5py

LIBVER = ("v110", "v114")
PAGE = 4096
#: Links of ``/runs`` kept in its object header (HDF5's maximum; the default 8 switches to a fractal heap).
MAX_COMPACT = 65535
#: Run groups whose links fit in ``/runs``'s first header chunk (the first page of the file).
EST_RUNS = 120
#: Attributes kept in a run group's object header before HDF5 would move them to dense storage.
MAX_COMPACT_ATTRS = 1000
#: Size hint of a run group's first header chunk, as links of 16-character names: room (about 2 KiB, one page)
#: for its ~10 links, its attributes and the attributes its end adds, so the end rewrites only that chunk.
EST_RUN_LINKS = 48


@functools.cache
def _hdf5() -> Any:
    """The HDF5 C library that h5py uses, or None if it cannot be found."""
    candidates: list[str] = []
    try:
        with open("/proc/self/maps") as maps:
            for line in maps:
                parts = line.split()
                name = Path(parts[-1]).name if len(parts) >= 6 else ""
                if name.startswith("libhdf5") and not name.startswith("libhdf5_hl") and parts[-1] not in candidates:
                    candidates.append(parts[-1])
    except OSError:
        pass
    candidates.append(h5py.h5p.__file__)  # statically linked builds export the symbols from the extension
    for path in candidates:
        try:
            lib = ctypes.CDLL(path)
            for fn in (lib.H5Pset_link_phase_change, lib.H5Pset_est_link_info):
                fn.argtypes = [ctypes.c_int64, ctypes.c_uint, ctypes.c_uint]
                fn.restype = ctypes.c_int
            lib.H5Pset_metadata_read_attempts.argtypes = [ctypes.c_int64, ctypes.c_uint]
            lib.H5Pget_metadata_read_attempts.argtypes = [ctypes.c_int64, ctypes.POINTER(ctypes.c_uint)]
            for fn in (lib.H5Pset_metadata_read_attempts, lib.H5Pget_metadata_read_attempts):
                fn.restype = ctypes.c_int
        except (OSError, AttributeError):
            continue
        return lib
    return None


def group_plist(*, links: int | None = None, name_len: int = 4) -> h5py.h5p.PropGCID:
    """Group-creation properties: no time stamps, compact attributes; with ``links``, compact links and a first
    header chunk sized for that many names of ``name_len`` characters."""
    gcpl = h5py.h5p.create(h5py.h5p.GROUP_CREATE)
    gcpl.set_obj_track_times(False)
    gcpl.set_attr_phase_change(MAX_COMPACT_ATTRS, 0)
    lib = _hdf5()
    if links is not None and lib is not None:
        if lib.H5Pset_link_phase_change(gcpl.id, MAX_COMPACT, MAX_COMPACT - 1) < 0:
            raise RuntimeError("H5Pset_link_phase_change failed")
        if lib.H5Pset_est_link_info(gcpl.id, links, name_len) < 0:
            raise RuntimeError("H5Pset_est_link_info failed")
    return gcpl


def create_group(parent: h5py.Group, name: str, *, links: int | None = None, name_len: int = 4) -> h5py.Group:
    """Create ``parent/name`` with `group_plist` properties."""
    gid = h5py.h5g.create(parent.id, name.encode(), gcpl=group_plist(links=links, name_len=name_len))
    return h5py.Group(gid)


def compact_links_supported() -> bool:
    """Whether the HDF5 library could be reached for the link-storage settings."""
    return _hdf5() is not None


#: HDF5's attempts at a metadata block whose checksum fails, for readers (module docstring; HDF5's SWMR default 100).
READ_ATTEMPTS = 20


def read_access() -> h5py.h5p.PropFAID:
    """File-access properties of every reader: h5py's defaults, HDF5 file locking off, and at most `READ_ATTEMPTS`
    tries of a metadata block whose checksum fails (HDF5's default when the library cannot be reached)."""
    fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    fapl.set_file_locking(False, True)
    lib = _hdf5()
    if lib is not None and lib.H5Pset_metadata_read_attempts(fapl.id, READ_ATTEMPTS) < 0:
        raise RuntimeError("H5Pset_metadata_read_attempts failed")
    return fapl


def read_attempts(fapl: h5py.h5p.PropFAID) -> int | None:
    """The metadata read attempts set in ``fapl`` (an open file's: ``h5.id.get_access_plist()``), None if the
    library cannot be reached."""
    lib = _hdf5()
    value = ctypes.c_uint()
    if lib is None or lib.H5Pget_metadata_read_attempts(fapl.id, ctypes.byref(value)) < 0:
        return None
    return value.value


def file_access() -> h5py.h5p.PropFAID:
    """File-access properties for the sec2 driver: the format bounds above and HDF5 file locking off (the log
    has its own lock, see `rig.session.locks`); otherwise h5py's defaults, so that a reader in the same process
    (same settings as `rig.session.reader.open_session`) can share the open file."""
    fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    fapl.set_libver_bounds(h5py.h5f.LIBVER_V110, h5py.h5f.LIBVER_V114)
    fapl.set_file_locking(False, True)
    return fapl
