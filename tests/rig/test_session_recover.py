"""``rig sessions recover`` (`rig.session.recover`) after ``kill -9`` of the writer at random moments: a crashed
file is told from one being written, recovery is refused while a writer lives, clears the writer flags so that
plain ``h5py.File(path, "r")`` opens the file, marks the cut run interrupted, leaves every sample byte-identical,
and ``--resume`` (the next writer process) still works afterwards.

The writer processes are those of test_session_log.py (8 accelerometers at 1 kHz, real time).
"""

from __future__ import annotations

import json
import random
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from rig.session import (
    CLOSED,
    CRASHED,
    WRITING,
    SessionError,
    list_sessions,
    read_session,
    recover,
    writer_flags,
    writer_state,
)
from tests.helpers.cli import rig
from tests.helpers.session_writer import WriterChild, final_resume_and_run, writer_config


def _samples(path: Path, swmr: bool) -> dict[str, bytes]:
    """Every dataset under /runs as (shape, dtype, bytes): what "byte-identical samples" compares."""
    out: dict[str, bytes] = {}
    with h5py.File(path, "r", swmr=swmr, locking=False) as h5:
        def visit(name: str, obj: object) -> None:
            if isinstance(obj, h5py.Dataset):
                data = obj[()]
                out[name] = repr((data.shape, data.dtype.str)).encode() + np.ascontiguousarray(data).tobytes()

        h5["runs"].visititems(visit)
    return out


def _statuses(path: Path) -> dict[str, str]:
    return {run["name"]: run["status"] for run in read_session(path, data=False)["runs"]}


def _recover_after_kills(tmp_path: Path, kills: int, seed: int) -> int:
    """A chain of writers, each resuming the session and killed at a random moment; after each kill the file is
    recovered and checked. Returns how many kills left a crashed file (writer flags set)."""
    rng = random.Random(seed)
    path = tmp_path / "session.h5"
    crashed = 0
    for i in range(kills):
        child = WriterChild(writer_config(path, tmp_path / f"progress{i}.txt", seed * 100 + i, sensors=4,
                               run_seconds=(0.3, 1.2)))
        if not child.wait_marker("c" if i == 0 else "r", timeout=60):
            pytest.fail(f"writer never started: {child.stderr()}")
        time.sleep(rng.uniform(0.05, 1.5))
        child.kill()
        state = writer_state(path)
        assert state in (CLOSED, CRASHED)
        before = _samples(path, swmr=True)
        statuses = _statuses(path)
        if state == CRASHED:
            crashed += 1
            assert writer_flags(path) != 0
            with pytest.raises(OSError):
                h5py.File(path, "r").close()  # what the issue saw: only SWMR readers open a crashed file
        done = recover(path)
        assert done.state == state and bool(done.flags) == (state == CRASHED)
        assert writer_state(path) == CLOSED and writer_flags(path) == 0
        with h5py.File(path, "r") as h5:  # plain read, HDF5 file locking on: any HDF5 program opens it now
            assert len(h5["runs"]) == len(statuses)
        assert _samples(path, swmr=False) == before  # every sample on disk byte-identical
        after = _statuses(path)
        cut = {name for name, status in statuses.items() if status == "running"}
        assert set(done.interrupted) == cut
        assert after == {name: ("interrupted" if name in cut else status) for name, status in statuses.items()}
        assert recover(path).changed is False  # a second recovery finds nothing to do
    final_resume_and_run(path, 4)  # --resume still works after recoveries
    return crashed


@pytest.mark.integration
def test_recover_after_kill_minus_9_at_random_moments(tmp_path: Path) -> None:
    crashed = _recover_after_kills(tmp_path, kills=6, seed=16)
    assert crashed >= 3  # most kills land inside a run (the writers run back to back)


@pytest.mark.integration
@pytest.mark.slow
def test_recover_after_kill_minus_9_at_random_moments_many(tmp_path: Path) -> None:
    crashed = _recover_after_kills(tmp_path, kills=40, seed=1616)
    assert crashed >= 20


@pytest.mark.integration
def test_a_live_writer_is_told_apart_and_the_cli_names_the_recover_command(tmp_path: Path) -> None:
    path = tmp_path / "live.h5"
    child = WriterChild(writer_config(path, tmp_path / "progress.txt", 7, sensors=2, run_seconds=(30.0, 30.0)))
    try:
        if not child.wait_marker("b", timeout=60):
            pytest.fail(f"writer never began a run: {child.stderr()}")
        assert writer_state(path) == WRITING
        assert [s["state"] for s in list_sessions(tmp_path)] == [WRITING]
        with pytest.raises(SessionError, match=r"a live session log .* is writing this file; .* nothing was changed"):
            recover(path)
        assert writer_flags(path) != 0  # untouched
        listed = rig("sessions", "list", str(tmp_path))
        assert "writing" in listed.stdout and "CRASHED" not in listed.stdout
    finally:
        child.kill()
    assert writer_state(path) == CRASHED
    assert [s["state"] for s in list_sessions(tmp_path)] == [CRASHED]
    command = f"rig sessions recover {path}"
    listed = rig("sessions", "list", str(tmp_path))
    assert "CRASHED: rig sessions recover" in listed.stdout
    shown = rig("sessions", "show", str(path))
    assert shown.exit_code == 0 and command in shown.stderr and "running" in shown.stdout
    analysed = rig("analyze", str(path))
    assert analysed.exit_code == 2 and command in analysed.stderr
    assert len(analysed.stderr.splitlines()) == 1
    reported = rig("report", str(path), "-o", str(tmp_path / "r.html"), "--json")
    assert command in reported.stderr
    recovered = rig("sessions", "recover", str(path), "--json")
    assert recovered.exit_code == 0, recovered.stderr
    result = json.loads(recovered.stdout)
    assert result["state"] == CRASHED and result["changed"] and len(result["interrupted"]) == 1
    assert _statuses(path)[result["interrupted"][0]] == "interrupted"
    listed = rig("sessions", "list", str(tmp_path))
    assert "CRASHED" not in listed.stdout and "writing" not in listed.stdout
    shown = rig("sessions", "show", str(path))
    assert shown.stderr == ""
    again = rig("sessions", "recover", str(path))
    assert again.exit_code == 0 and "nothing to recover" in again.stdout


def test_recover_refuses_what_is_not_a_session_file(tmp_path: Path) -> None:
    other = tmp_path / "notes.h5"
    other.write_bytes(b"not hdf5 at all" * 10)
    with pytest.raises(SessionError, match="no HDF5 signature"):
        recover(other)
    with pytest.raises(SessionError, match="no such session file"):
        recover(tmp_path / "missing.h5")
    assert other.read_bytes() == b"not hdf5 at all" * 10
