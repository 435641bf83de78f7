"""Errors of the session log."""

from __future__ import annotations

import os

#: What ``rig sessions recover`` can and cannot do for a damaged file, said in every `DamagedFileError`.
RECOVER_CANNOT = ("rig sessions recover cannot repair it (it only clears the writer flags a killed rig run leaves "
                  "and marks the cut run interrupted); restore the file from a copy")


class SessionError(Exception):
    """A session file cannot be written or read as asked; the message names the file and what was expected."""


class SessionExistsError(SessionError, FileExistsError):
    """The session file to create already exists (a session file is never overwritten)."""


class DamagedFileError(SessionError):
    """The file's bytes are not a whole HDF5 session file (truncated, overwritten, bit-flipped): the message names
    the file, what is wrong and where, and what ``rig sessions recover`` can and cannot do. ``label`` is the word
    the command line prints before it (``damaged: …``)."""

    label = "damaged"

    def __init__(self, path: str | os.PathLike[str], what: str) -> None:
        super().__init__(f"{path}: {what}; {RECOVER_CANNOT}")
        self.path = str(path)
        self.what = what
