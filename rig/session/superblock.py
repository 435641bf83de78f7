"""The HDF5 superblock (format versions 2 and 3) at byte 0 of a session file: read it, and patch it in place.

Only what the session log needs: the file consistency flags that an HDF5 writer sets while the file is open
for writing (and leaves set if the writer is killed), and the end-of-allocation address (EOA, bytes). The
layout (HDF5 file format specification, "Superblock version 2 and 3"), with 8-byte addresses::

    0  signature (8)   8  version (1)   9  size of offsets (1)   10  size of lengths (1)   11  flags (1)
    12 base address    20 superblock extension address    28 end-of-file address    36 root group header address
    44 checksum (4, Jenkins lookup3 of bytes 0..43)

All 48 bytes lie in the first page of the file, so rewriting them is one ``pwrite`` inside one page, which a
``kill -9`` cannot tear (the kernel copies a page into the page cache as a whole once it has started).
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass

from .errors import DamagedFileError

SIGNATURE = b"\x89HDF\r\n\x1a\n"
#: Bytes of a version 2/3 superblock with 8-byte offsets.
SIZE = 48
#: Consistency flags (version 3): bit 0 "open for writing", bit 2 "open for SWMR writing".
WRITE_ACCESS = 0x01
SWMR_WRITE_ACCESS = 0x04
_EOA = slice(28, 36)
#: HDF5's "undefined address" (all bits set).
UNDEFINED = 0xFFFFFFFFFFFFFFFF
_MASK = 0xFFFFFFFF


def _rot(x: int, k: int) -> int:
    return ((x << k) | (x >> (32 - k))) & _MASK


def _mix(a: int, b: int, c: int) -> tuple[int, int, int]:
    a = (a - c) & _MASK; a ^= _rot(c, 4); c = (c + b) & _MASK  # noqa: E702
    b = (b - a) & _MASK; b ^= _rot(a, 6); a = (a + c) & _MASK  # noqa: E702
    c = (c - b) & _MASK; c ^= _rot(b, 8); b = (b + a) & _MASK  # noqa: E702
    a = (a - c) & _MASK; a ^= _rot(c, 16); c = (c + b) & _MASK  # noqa: E702
    b = (b - a) & _MASK; b ^= _rot(a, 19); a = (a + c) & _MASK  # noqa: E702
    c = (c - b) & _MASK; c ^= _rot(b, 4); b = (b + a) & _MASK  # noqa: E702
    return a, b, c


def _final(a: int, b: int, c: int) -> int:
    c ^= b; c = (c - _rot(b, 14)) & _MASK  # noqa: E702
    a ^= c; a = (a - _rot(c, 11)) & _MASK  # noqa: E702
    b ^= a; b = (b - _rot(a, 25)) & _MASK  # noqa: E702
    c ^= b; c = (c - _rot(b, 16)) & _MASK  # noqa: E702
    a ^= c; a = (a - _rot(c, 4)) & _MASK  # noqa: E702
    b ^= a; b = (b - _rot(a, 14)) & _MASK  # noqa: E702
    c ^= b; c = (c - _rot(b, 24)) & _MASK  # noqa: E702
    return c


def lookup3(data: bytes, initval: int = 0) -> int:
    """Bob Jenkins' lookup3 ``hashlittle`` as HDF5's ``H5_checksum_lookup3`` computes it (byte-wise)."""
    length = len(data)
    a = b = c = (0xDEADBEEF + length + initval) & _MASK
    i = 0
    while length > 12:
        a = (a + int.from_bytes(data[i : i + 4], "little")) & _MASK
        b = (b + int.from_bytes(data[i + 4 : i + 8], "little")) & _MASK
        c = (c + int.from_bytes(data[i + 8 : i + 12], "little")) & _MASK
        a, b, c = _mix(a, b, c)
        i += 12
        length -= 12
    if length == 0:
        return c
    tail = data[i:].ljust(12, b"\0")
    a = (a + int.from_bytes(tail[0:4], "little")) & _MASK
    b = (b + int.from_bytes(tail[4:8], "little")) & _MASK
    c = (c + int.from_bytes(tail[8:12], "little")) & _MASK
    return _final(a, b, c)


@dataclass(frozen=True)
class Superblock:
    """A parsed version 2/3 superblock; addresses in bytes from the start of the file."""

    version: int
    flags: int
    eoa: int
    root: int
    raw: bytes
    #: Base address (0 in a session file) and the superblock extension's address (`UNDEFINED` if none).
    base: int = 0
    extension: int = 0

    def patched(self, *, flags: int | None = None, eoa: int | None = None) -> bytes:
        """The 48 bytes with new consistency flags and/or EOA [bytes], and the checksum recomputed."""
        body = bytearray(self.raw[: SIZE - 4])
        if flags is not None:
            body[11] = flags
        if eoa is not None:
            body[_EOA] = struct.pack("<Q", eoa)
        return bytes(body) + struct.pack("<I", lookup3(bytes(body)))


def parse(raw: bytes, where: str | os.PathLike[str] = "file") -> Superblock:
    """Parse the first bytes of a session file; `DamagedFileError` (a `SessionError`) if they are not a version 2/3
    superblock."""
    if len(raw) < SIZE or raw[:8] != SIGNATURE:
        raise DamagedFileError(where, "no HDF5 signature at byte 0 (not a shaketable-rig session file, or its first "
                                      "bytes are lost)")
    version, offsets, lengths = raw[8], raw[9], raw[10]
    if version not in (2, 3) or offsets != 8 or lengths != 8:
        raise DamagedFileError(where, f"HDF5 superblock version {version} with {offsets}-byte addresses at byte 8; "
                                      "expected version 2 or 3 with 8-byte addresses (a session file written by "
                                      "rig.session)")
    (stored,) = struct.unpack("<I", raw[44:48])
    if lookup3(raw[:44]) != stored:
        raise DamagedFileError(where, "the HDF5 superblock checksum (bytes 44-47) does not match its bytes 0-43")
    base, extension, eoa, root = struct.unpack("<QQQQ", raw[12:44])
    return Superblock(version=version, flags=raw[11], eoa=eoa, root=root, raw=bytes(raw[:SIZE]), base=base,
                      extension=extension)


def read(fd: int, where: str | os.PathLike[str] = "file") -> Superblock:
    """Read and parse the superblock of the open file ``fd``."""
    return parse(os.pread(fd, SIZE, 0), where)


def _ext_time_ranges(page: bytes, ext: int) -> list[tuple[int, int]] | None:
    """Byte ranges of the time stamps and checksum of the superblock-extension object header at ``ext`` (a version
    2 header, "OHDR"), or None if it is not a single-chunk header inside ``page`` that stores times."""
    if ext + 8 > len(page) or page[ext : ext + 4] != b"OHDR" or page[ext + 4] != 2:
        return None
    flags = page[ext + 5]
    if not flags & 0x20:  # no time stamps
        return None
    at = ext + 6 + 16 + (4 if flags & 0x10 else 0)
    width = 1 << (flags & 0x03)
    chunk = int.from_bytes(page[at : at + width], "little")
    checksum = at + width + chunk
    if checksum + 4 > len(page):
        return None
    return [(ext + 6, ext + 22), (checksum, checksum + 4)]


def superblock_only_change(old: bytes, new: bytes) -> bool:
    """True if two versions of page 0 differ only in fields whose change alone leaves the file's structure as it was:
    the superblock's EOA and checksum, and the time stamps (and checksum) of the superblock-extension header,
    which HDF5 rewrites with the current time on every close of a paged file."""
    if len(old) < SIZE or len(new) < SIZE or old[:28] != new[:28] or old[36:44] != new[36:44]:
        return False
    allowed = [(28, 36), (44, 48)]
    ext = int.from_bytes(old[20:28], "little")
    if ext != UNDEFINED:
        ranges = _ext_time_ranges(old, ext)
        if ranges is not None and ranges == _ext_time_ranges(new, ext):
            allowed += ranges
    differing = (i for i in range(min(len(old), len(new))) if old[i] != new[i])
    return len(old) == len(new) and all(any(a <= i < b for a, b in allowed) for i in differing)
