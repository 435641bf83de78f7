"""A session file after its writer was killed (``kill -9``, a power cut): recognise it, and recover it without a table.

A killed SWMR writer leaves the superblock's "open for writing" flags set: plain ``h5py.File(path, "r")`` and
HDFView refuse the file (only SWMR readers open it), and the run being recorded keeps the status ``"running"``.
`writer_state` tells such a *crashed* file from one being written (a live session log holds the writer's lock,
`rig.session.locks`). `recover` does what ``rig run --resume`` does before its first run, and nothing more:

1. take the writer's locks (refused, nothing changed, if a live writer holds the file);
2. clear the flags (one write in the superblock page, `rig.session.atomic.SessionFile.clear_open_flags`);
3. mark runs still ``"running"`` as ``"interrupted"`` (``ended`` = now), in one atomic transaction;
4. release the file.

Samples on disk are not touched (the datasets keep every byte; only superblock, run-group attributes and their
metadata change), and the session can still be continued with ``rig run --resume`` afterwards.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from . import schema, space
from .errors import SessionError
from .log import SessionLog
from .reader import CLOSED, CRASHED, WRITING, read_session, writer_flags, writer_state

__all__ = ["CLOSED", "CRASHED", "WRITING", "Recovery", "crashed_message", "recover", "recover_command",
           "writer_state"]


def recover_command(path: str | os.PathLike[str]) -> str:
    """The command that recovers ``path`` (named in every message about a crashed file)."""
    return f"rig sessions recover {path}"


def crashed_message(path: str | os.PathLike[str]) -> str:
    """Why a crashed file needs recovering, and the command that does it."""
    return (f"{path}: the session's writer was killed (the file is still marked open for writing, no writer holds "
            f"it); recover it with `{recover_command(path)}` (or continue it with `rig run --resume {path}`)")


@dataclass(frozen=True)
class Recovery:
    """What `recover` did: ``state`` before (`writer_state`), flags before, runs marked interrupted."""

    path: Path
    state: str
    flags: int
    interrupted: tuple[str, ...]

    @property
    def changed(self) -> bool:
        return bool(self.flags or self.interrupted)

    def as_dict(self) -> dict[str, object]:
        return {"path": str(self.path), "state": self.state, "flags_before": self.flags,
                "interrupted": list(self.interrupted), "changed": self.changed}


def recover(path: str | os.PathLike[str]) -> Recovery:
    """Recover a crashed session file (module docstring); a file that needs nothing is left as it is.

    Raises `SessionError` naming the file if it is not a session file, or if a live writer holds it, and
    `~rig.session.space.DiskFullError` when its file system has not :data:`~rig.session.space.RECOVER_NEEDS` free
    (in each case nothing is changed)."""
    path = Path(path)
    if not path.is_file():
        raise SessionError(f"{path}: no such session file")
    state = writer_state(path)
    if state == WRITING:
        raise SessionError(f"{path}: a live session log (rig run) is writing this file; it has not crashed and "
                           "needs no recovery — nothing was changed")
    flags = writer_flags(path)
    before = {run["name"]: run["status"] for run in read_session(path, data=False)["runs"]}
    if flags or schema.RUNNING in before.values():  # it will write: only with room to finish
        space.check_room(path, space.RECOVER_NEEDS, "recovering it")
    try:
        log = SessionLog.resume(path)
    except SessionError as exc:
        if "another process" in str(exc):
            raise SessionError(f"{path}: a writer took the file while it was being recovered; nothing was "
                               f"changed ({exc})") from None
        raise
    try:
        interrupted = tuple(run.name for run in log.runs()
                            if before.get(run.name) == schema.RUNNING and run.status == "interrupted")
    finally:
        log.close()
    return Recovery(path=path, state=state, flags=flags, interrupted=interrupted)
