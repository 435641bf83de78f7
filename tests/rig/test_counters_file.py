"""Issue 42, item 6 (its first part): the emulator's counters file ``SESSION.emulator.json`` on a full disk — a clear
message and an orderly end, never an ``OSError`` traceback; the session file as the session left it."""

from __future__ import annotations

import errno
import json
import os
import resource
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from rig.orchestrator.setup import CountersNotWrittenError, write_emulator_counters
from rig.session import read_session
from tests.helpers.sequences import TINY_ONE_RUN

COUNTERS = {"underruns": 0, "refused_commands": 0, "overturns": []}


def no_room(monkeypatch: pytest.MonkeyPatch, *, written: int = 0) -> None:
    """Make writing a ``*.emulator.json`` fail as on a full disk (ENOSPC) after ``written`` characters."""
    real = Path.write_text

    def full(self: Path, data: str, *args: object, **kwargs: object) -> int:
        if not self.name.endswith(".emulator.json"):
            return real(self, data, *args, **kwargs)
        if written:
            real(self, data[:written])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))

    monkeypatch.setattr(Path, "write_text", full)


def test_the_counters_are_written_beside_the_session(tmp_path: Path) -> None:
    path = write_emulator_counters(tmp_path / "s.h5", COUNTERS)
    assert path == tmp_path / "s.emulator.json" and json.loads(path.read_text()) == COUNTERS


@pytest.mark.parametrize("written", [0, 10])
def test_a_full_disk_is_a_clear_error_and_leaves_no_part_of_the_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, written: int) -> None:
    no_room(monkeypatch, written=written)
    with pytest.raises(CountersNotWrittenError) as raised:
        write_emulator_counters(tmp_path / "s.h5", COUNTERS)
    assert str(raised.value) == (f"disk full: {tmp_path / 's.emulator.json'}: the emulator's counters were not "
                                 "written (No space left on device); the session file is not affected")
    assert not (tmp_path / "s.emulator.json").exists()


def test_another_write_error_says_so(tmp_path: Path) -> None:
    (tmp_path / "s.emulator.json").mkdir()  # a directory where the file goes
    with pytest.raises(CountersNotWrittenError, match=r"^cannot write: .*s\.emulator\.json: the emulator's counters"):
        write_emulator_counters(tmp_path / "s.h5", COUNTERS)


# ----- rig run: the disk ends the session, then the counters find no room either ------------------------------


RIG_WITHOUT_ROOM = textwrap.dedent("""
    import errno, os, pathlib, runpy, sys

    real = pathlib.Path.write_text

    def full(self, data, *args, **kwargs):
        if self.name.endswith(".emulator.json"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))
        return real(self, data, *args, **kwargs)

    pathlib.Path.write_text = full
    sys.argv = ["rig", *sys.argv[1:]]
    runpy.run_module("rig.cli", run_name="__main__")
""")

FILE_LIMIT = 150_000
"""RLIMIT_FSIZE [bytes]: the session file is created, the first run's transaction finds no room (as
``tests/rig/test_cli_run.py``'s first full-disk test)."""


@pytest.mark.integration  # starts rig and the emulator's process
def test_rig_run_ends_in_order_when_the_counters_find_no_room_after_a_disk_full_end(tmp_path: Path) -> None:
    def limited() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (FILE_LIMIT, FILE_LIMIT))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)

    (tmp_path / "tiny.toml").write_text(TINY_ONE_RUN)
    session = tmp_path / "s.h5"
    done = subprocess.run([sys.executable, "-c", RIG_WITHOUT_ROOM, "run", "tiny.toml", "--emulate", "--speed", "max",
                           "--yes", "-o", str(session)], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                          preexec_fn=limited, env={**os.environ, "COLUMNS": "200"})
    out = done.stdout + done.stderr
    assert done.returncode == 1, out[-3000:]
    assert "Traceback" not in out and "OSError" not in out
    assert "faulted: disk full: " in done.stdout
    assert (f"warning: disk full: {tmp_path / 's.emulator.json'}: the emulator's counters were not written (No "
            "space left on device); the session file is not affected") in done.stderr
    assert f"rig run --resume {session}" in done.stdout  # the orderly end after a full disk
    assert not (tmp_path / "s.emulator.json").exists()
    assert read_session(session)["runs"] == []
