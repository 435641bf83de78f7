"""Reading a private file — the rig's signing key, the console's tokens file, a zenoh process's TLS key — once.

:func:`read_private_file` opens the file and refuses it, before reading, when it is not a regular file or when
group or others may access it (mode & 0o077, as ssh refuses a private key), saying the ``chmod 600`` to run. Each
refusal is one :class:`PrivateFileError` line starting with the caller's ``where`` (the option or file the path
came from); the caller turns it into its own error type.
"""

from __future__ import annotations

import os
import shlex
import stat
from pathlib import Path


class PrivateFileError(ValueError):
    """A private file that cannot be read: one line naming where it came from and what is wrong."""


class SharedPrivateFileError(PrivateFileError):
    """A private file that group or others may access; ``mode`` is its permission bits (``stat.S_IMODE``)."""

    def __init__(self, message: str, mode: int) -> None:
        super().__init__(message)
        self.mode = mode


def read_private_file(path: Path, where: str, what: str, max_bytes: int) -> bytes:
    """At most ``max_bytes + 1`` bytes of ``path`` (the caller refuses a longer file in its own words).

    :class:`PrivateFileError` ``"{where}: not a regular file"`` or ``"{where}: {the OS's reason}"`` (its cause the
    :class:`OSError`); :class:`SharedPrivateFileError` ``"{where}: mode 0644 lets other users read {what}; run:
    chmod 600 PATH"`` on POSIX when group or others may access it. ``what`` names the content (``the rig's key``).
    """
    try:
        with path.open("rb") as file:
            info = os.fstat(file.fileno())
            if not stat.S_ISREG(info.st_mode):
                raise PrivateFileError(f"{where}: not a regular file")
            mode = stat.S_IMODE(info.st_mode)
            if os.name == "posix" and mode & 0o077:
                raise SharedPrivateFileError(f"{where}: mode {mode:04o} lets other users read {what}; run: "
                                             f"chmod 600 {shlex.quote(str(path))}", mode)
            return file.read(max_bytes + 1)
    except OSError as exc:
        raise PrivateFileError(f"{where}: {exc.strerror or exc}") from exc
