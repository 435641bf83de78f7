"""What can be told about an HDF5 file of ours before HDF5 reads it, and opening it for reading with HDF5 bounded.

HDF5 trusts the addresses a file holds: a truncated or overwritten file sends it reading beyond the end (zeros),
where every metadata checksum fails, and a SWMR reader then retries each block with growing sleeps, for ever in
practice (`rig.session.hdf5props.READ_ATTEMPTS`). So, from the first page of the file, in Python:

1. the size: at least a superblock (48 bytes);
2. the HDF5 signature at byte 0 (our files have no user block);
3. the superblock: version 2 or 3 with 8-byte addresses and a matching checksum (a session file,
   `rig.session.superblock`), or version 0/1 (a study file) when any file of ours is accepted;
4. its addresses: base address 0, the root group's header and the superblock extension inside the file;
5. the end-of-file address (EOA) against the file's size. A file that no writer has open holds every byte up to
   its EOA. A session file whose writer has it open, or was killed (superblock flags set), may lack the tail that
   HDF5 allocated but had not written yet (`rig sessions recover` extends it), never its first page, which holds
   the superblock, the root group and ``/runs``.

A file that fails one of these is refused with `DamagedFileError` ("FILE: what is wrong; what ``rig sessions
recover`` can and cannot do"). One that passes is opened with `hdf5props.read_access` (HDF5's retries bounded), so
that damage deeper in the file ends as an HDF5 error within milliseconds, which the readers word the same way.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

import h5py

from . import superblock
from .errors import DamagedFileError, SessionError
from .hdf5props import PAGE, read_access


def _read_head(path: Path) -> tuple[bytes, int]:
    """The first page of ``path`` and the file's size [bytes]; `SessionError` if it cannot be read."""
    try:
        with open(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            return f.read(PAGE), size
    except FileNotFoundError:
        raise SessionError(f"{path}: no such session file") from None
    except OSError as exc:
        raise SessionError(f"{path}: cannot read the file ({exc.strerror})") from None


def _addresses(path: Path, size: int, eoa: int, named: dict[str, int]) -> None:
    """Each named address inside the file: at or after the superblock, below the EOA and the file's size."""
    for name, address in named.items():
        if address != superblock.UNDEFINED and not superblock.SIZE <= address < min(eoa, size):
            raise DamagedFileError(path, f"the superblock's {name} address is {address}, outside the file's "
                                         f"{min(eoa, size)} bytes")


def _truncated(path: Path, size: int, eoa: int) -> DamagedFileError:
    return DamagedFileError(path, f"truncated: the file has {size} bytes, its HDF5 superblock says {eoa}")


def check_session(path: str | os.PathLike[str]) -> superblock.Superblock:
    """Checks 1–5 of the module docstring for a session file (superblock version 2/3); its parsed superblock.
    `DamagedFileError` naming the file and what is wrong, `SessionError` if it cannot be read at all."""
    path = Path(path)
    head, size = _read_head(path)
    if size < superblock.SIZE:
        raise DamagedFileError(path, f"the file has {size} bytes, fewer than an HDF5 superblock ({superblock.SIZE})")
    sb = superblock.parse(head, path)
    if sb.base != 0:
        raise DamagedFileError(path, f"the superblock's base address is {sb.base}; expected 0 (no user block)")
    if sb.flags == 0 and size < sb.eoa:
        raise _truncated(path, size, sb.eoa)
    if size < min(sb.eoa, PAGE):
        raise DamagedFileError(path, f"truncated: the file has {size} bytes, less than its first page ({PAGE}) "
                                     "that holds the superblock and the root group")
    _addresses(path, size, sb.eoa, {"root group": sb.root, "superblock extension": sb.extension})
    return sb


def check_hdf5(path: str | os.PathLike[str]) -> None:
    """`check_session` for a session file; for an older superblock (version 0/1: a study file) the signature, the
    base address and the EOA against the size. `DamagedFileError` / `SessionError` as `check_session`."""
    path = Path(path)
    head, size = _read_head(path)
    if len(head) >= 9 and head[:8] == superblock.SIGNATURE and head[8] in (0, 1):
        at = 24 if head[8] == 0 else 28  # after the fixed fields of a version 0 / 1 superblock
        if len(head) < at + 24 or head[13] != 8:
            raise DamagedFileError(path, f"HDF5 superblock version {head[8]} with {head[13]}-byte addresses; "
                                         "expected 8-byte addresses (a file written by rig)")
        base, _free_space, eoa = struct.unpack("<QQQ", head[at : at + 24])
        if base != 0:
            raise DamagedFileError(path, f"the superblock's base address is {base}; expected 0 (no user block)")
        if size < eoa:
            raise _truncated(path, size, eoa)
        return
    check_session(path)


def hdf5_error(path: str | os.PathLike[str], exc: BaseException, where: str = "") -> DamagedFileError:
    """What HDF5 said about a file that passed the checks above (a damaged block inside it), as `DamagedFileError`
    naming the object being read (``where``, e.g. ``/runs/0002/accel/plate``)."""
    detail = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
    return DamagedFileError(path, f"HDF5 cannot read {where or 'its structure'} ({detail})")


def open_read(path: str | os.PathLike[str], *, swmr: bool = True) -> h5py.File:
    """The file opened read-only (as a SWMR reader by default) with `hdf5props.read_access`, after no check:
    call `check_session` or `check_hdf5` first. Raises what h5py raises (OSError)."""
    flags = h5py.h5f.ACC_RDONLY | (h5py.h5f.ACC_SWMR_READ if swmr else 0)
    return h5py.File(h5py.h5f.open(os.fsencode(path), flags, fapl=read_access()))
