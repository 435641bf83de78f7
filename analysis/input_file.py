"""A user's input file read safely: only a regular file, its size bounded before a byte is read.

Record files, sequence files and rig configurations all come from the user. A FIFO would block the reader
forever, ``/dev/zero`` or ``/dev/urandom`` (also behind a symlink) would fill memory, and a huge file would
do the same: :func:`read_regular_file` refuses all of them with an `InputFileError` whose message says what
the path is and what was expected (the caller prefixes the file name). The path is checked with ``stat``
before it is opened (opening some devices has effects of its own), opened without blocking, checked again
on the open descriptor (the file may have been swapped in between), and read up to its bound only, so a
file that grows while it is read is refused too.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

MIB = 1 << 20
"""One mebibyte [bytes]."""


class InputFileError(ValueError):
    """An input file that cannot be read (missing, not a regular file, too large); the message has no path."""


def _kind(mode: int) -> str:
    """What a non-regular file is, in words."""
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def _check(mode: int, size: int, max_bytes: int, expected: str) -> None:
    """Refuse anything but a regular file of at most ``max_bytes`` bytes."""
    if not stat.S_ISREG(mode):
        raise InputFileError(f"is {_kind(mode)}; expected {expected} (a regular file)")
    if size > max_bytes:
        raise InputFileError(f"is {size:,} bytes; expected {expected} of at most {max_bytes:,} bytes")


def read_regular_file(path: str | Path, max_bytes: int, expected: str = "a file") -> bytes:
    """The bytes of ``path`` if it is a regular file (symlinks followed) of at most ``max_bytes`` bytes.

    Args:
        path: the file.
        max_bytes: the largest size accepted [bytes].
        expected: what the file should be, for the messages (e.g. ``"a sequence file"``).

    Raises:
        InputFileError: no such file, not a regular file (directory, FIFO, device, socket), larger than
            ``max_bytes`` (also when it grows while read), or unreadable.
    """
    path = Path(path).expanduser()
    try:
        before = os.stat(path)
        _check(before.st_mode, before.st_size, max_bytes, expected)
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise InputFileError("no such file") from None
    except OSError as exc:
        raise InputFileError(f"cannot read ({exc.strerror or exc})") from None
    try:
        opened = os.fstat(fd)
        _check(opened.st_mode, opened.st_size, max_bytes, expected)
        # One read of the whole file (one byte more, to see it grow): joining chunks would hold it twice.
        data = os.read(fd, max_bytes + 1 if opened.st_size >= max_bytes else opened.st_size + 1)
        chunks: list[bytes] = [data]
        left = max_bytes + 1 - len(data)
        while data and left > 0:  # a short read: the rest by chunks
            chunk = os.read(fd, min(left, MIB))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
    except OSError as exc:
        raise InputFileError(f"cannot read ({exc.strerror or exc})") from None
    finally:
        os.close(fd)
    data = chunks[0] if len(chunks) == 1 else b"".join(chunks)
    if len(data) > max_bytes:
        raise InputFileError(f"grew beyond {max_bytes:,} bytes while it was read; expected {expected} that stays put")
    return data
