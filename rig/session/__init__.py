"""The crash-safe session log: one HDF5 file per session (schema ``shaketable-rig/session/1``, docs/architecture.md §6).

Writing::

    log = SessionLog.create(path, rig_config, sequence, software_version)   # or SessionLog.resume(path)
    run = log.begin_run(plan_index, record=..., scale_factor=..., angle_deg=..., commanded=..., bodies=...,
                        sensors=["plate"])
    run.append_accel("plate", t, xyz)          # cheap, any thread; on disk within `FLUSH_INTERVAL` s
    run.end("completed")
    log.close()

After a crash (writer killed): `writer_state` says ``"crashed"``, `recover` (``rig sessions recover``) clears the
writer flags and marks the cut run interrupted without a table. Reading (any process, any time, also during a run
or after a crash): `read_session`, `list_sessions`, or
``h5py.File(path, "r", swmr=True)`` — see `rig.session.reader`. Layout and units: `rig.session.schema`.
Crash safety: `rig.session.atomic` (structure changes) and `rig.session.writer` (samples).
"""

from .errors import DamagedFileError, SessionError, SessionExistsError
from .log import FLUSH_INTERVAL, MAX_FLUSH_INTERVAL, SessionLog
from .reader import list_sessions, open_session, read_session, writer_flags
from .recover import CLOSED, CRASHED, WRITING, Recovery, crashed_message, recover, recover_command, writer_state
from .run import RunLog
from .runinfo import RunInfo
from .schema import DONE_STATUSES, FINAL_STATUSES, RUNNING, SCHEMA
from .space import DiskFullError, check_room, is_disk_full, run_needs
from .writer import WriterStats

__all__ = [
    "CLOSED",
    "CRASHED",
    "DONE_STATUSES",
    "FINAL_STATUSES",
    "FLUSH_INTERVAL",
    "MAX_FLUSH_INTERVAL",
    "RUNNING",
    "SCHEMA",
    "WRITING",
    "DamagedFileError",
    "DiskFullError",
    "Recovery",
    "RunInfo",
    "RunLog",
    "SessionError",
    "SessionExistsError",
    "SessionLog",
    "WriterStats",
    "check_room",
    "crashed_message",
    "is_disk_full",
    "list_sessions",
    "open_session",
    "read_session",
    "recover",
    "recover_command",
    "run_needs",
    "writer_flags",
    "writer_state",
]
