"""``rig run`` end to end: the command line, the emulator as its own process over loopback UDP (MAVLink), the
session file read back. The quick sequence unattended; ``kill -9`` mid-record and ``--resume``; Ctrl-C; bad
sequence files refused before the table moves; a full disk.

``rig`` runs in this process (``tests.helpers.cli.rig``) except where its process is what is checked: ``kill -9``
and what it leaves, Ctrl-C sent to its process group, and a full disk (a file-size limit of the process; the
session then ends with ``os._exit``, which would end the test's own process)."""

from __future__ import annotations

import contextlib
import json
import math
import os
import resource
import signal
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest

from rig.sequence import load_sequence
from rig.session import read_session
from tests.helpers.cli import rig
from tests.helpers.processes import RIG, ROOT, child_of, running, start_tiny
from tests.helpers.sequences import TINY


@pytest.mark.integration
def test_the_quick_sequence_runs_unattended_and_logs_every_run(tmp_path: Path) -> None:
    session = tmp_path / "quick.h5"
    done = rig("run", str(ROOT / "examples" / "quick.toml"), "--emulate", "--speed", "max", "--yes", "-o", str(session),
               cwd=tmp_path)  # virtual time: the same session contents as at 1x (docs/table-controller.md)
    assert done.exit_code == 0, done.stderr + done.stdout
    sequence = load_sequence(ROOT / "examples" / "quick.toml")
    plan = sequence.plan()
    data = read_session(session)
    assert data["schema"] == "shaketable-rig/session/1" and data["sequence"]["name"] == "quick"
    runs = data["runs"]
    assert [(r["plan_index"], r["status"]) for r in runs] == [(p.plan_index, "completed") for p in plan]
    emulator = json.loads((tmp_path / "quick.emulator.json").read_text())
    assert emulator["underruns"] == 0 and emulator["streams_completed"] == len(plan)
    starts = []
    for run, planned in zip(runs, plan, strict=True):
        drive = sequence.prepare(planned)  # the commanded trajectory is the prepared drive, sample for sample
        np.testing.assert_array_equal(run["commanded"], np.column_stack([drive.t, drive.poses]))
        assert run["scale_factor"] == drive.scale_factor and run["angle_deg"] == planned.angle_deg
        t = run["accel"]["0"][:, 0]  # every sample over the drive's duration, none missing
        inside = t[(t >= -1e-9) & (t <= drive.duration + 1e-9)]  # ns → s rounding: virtual time is on the tick grid
        assert inside[0] < 1e-3 and inside[-1] > drive.duration - 1e-3
        np.testing.assert_allclose(np.diff(inside), 1e-3, atol=1e-9)
        assert abs(len(inside) - round(drive.duration * 1000)) <= 1  # both ends on the grid: duration × rate + 1
        # at rest on the plate tilted by β (x downhill): the specific force is −g in the plate frame,
        # (−g sin β, 0, g cos β), ± the sensor's noise
        tilt = math.radians(planned.angle_deg)
        rest = run["accel"]["0"][t < 0.2, 1:].mean(axis=0)
        np.testing.assert_allclose(rest, [-9.81 * math.sin(tilt), 0, 9.81 * math.cos(tilt)], atol=0.05)
        starts.append(run["attrs"]["t_start_controller_ns"] * 1e-9)
    # the detections of each run are the overturns the emulator reported in that run's time, body by body
    ids = [b.body_id for b in sequence.bodies]
    for k, run in enumerate(runs):
        end = starts[k + 1] if k + 1 < len(runs) else math.inf
        reported = sorted((ids[o["body_id"]], o["direction"]) for o in emulator["overturns"]
                          if starts[k] <= o["t"] < end)
        logged = sorted((d["body_id"], d["direction"]) for d in run["detections"])
        assert logged == reported
        assert all(d["source"] == "sensor" for d in run["detections"])
    assert sum(len(r["detections"]) for r in runs) == len(emulator["overturns"]) > 0


@pytest.mark.integration
@pytest.mark.slow  # 22 s; kill -9 of a writer is in the quick suite by test_session_recover and test_session_log
def test_kill_9_mid_record_keeps_the_samples_and_resume_finishes_the_session(tmp_path: Path) -> None:
    proc, session, seen = start_tiny(tmp_path)
    try:
        seen_at = time.monotonic()
        time.sleep(0.4)
        proc.send_signal(signal.SIGKILL)
        killed_at = time.monotonic()
        proc.wait()
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)  # the emulator it started
    with h5py.File(session, "r", swmr=True) as h5:  # the file opens
        assert h5["runs/0001"].attrs["status"] in (b"running", "running")
    cut = read_session(session)["runs"][0]
    last = cut["accel"]["0"][-1, 0]
    assert last >= seen + (killed_at - seen_at) - 1.0  # at most the last second lost

    done = rig("run", "--resume", str(session), "--emulate", "--yes", cwd=tmp_path)
    assert done.exit_code == 0, done.stderr + done.stdout
    runs = read_session(session)["runs"]
    assert [(r["plan_index"], r["status"]) for r in runs] == [(0, "interrupted"), (0, "completed"),
                                                              (1, "completed")]
    np.testing.assert_array_equal(runs[0]["accel"]["0"][: len(cut["accel"]["0"])], cut["accel"]["0"])



class Output:
    """A process's standard output, collected by a thread as it comes."""

    def __init__(self, proc: subprocess.Popen[bytes]) -> None:
        self.text = b""
        assert proc.stdout is not None
        self._thread = threading.Thread(target=self._read, args=(proc.stdout,), daemon=True)
        self._thread.start()

    def _read(self, stream: Any) -> None:
        for line in iter(stream.readline, b""):
            self.text += line

    def wait_for(self, needle: bytes, timeout: float = 120) -> None:
        deadline = time.monotonic() + timeout
        while needle not in self.text:
            assert time.monotonic() < deadline, self.text.decode(errors="replace")
            time.sleep(0.1)

    def join(self) -> bytes:
        self._thread.join(10)
        return self.text


@pytest.mark.integration
def test_ctrl_c_pauses_at_the_end_of_the_record_and_enter_resumes_also_unattended(tmp_path: Path) -> None:
    """``--yes`` too: the first Ctrl-C — sent to the whole process group, as a terminal does — pauses after the
    record being played (it completes, the next is not begun) and the emulator lives on in its own group; Enter
    resumes, and the session completes."""
    proc, session, _ = start_tiny(tmp_path, stdin=subprocess.PIPE)
    out = Output(proc)
    emulator = child_of(proc, b"sim_table")
    os.killpg(proc.pid, signal.SIGINT)  # the terminal's Ctrl-C reaches rig's whole process group
    out.wait_for(b"press Enter to resume")
    time.sleep(1.0)  # paused: nothing begins
    assert [r["status"] for r in read_session(session)["runs"]] == ["completed"]
    assert proc.poll() is None and Path(f"/proc/{emulator}").exists()  # the table did not die under the session
    assert proc.stdin is not None
    proc.stdin.write(b"\n")
    proc.stdin.flush()
    assert proc.wait(timeout=120) == 0, out.join().decode(errors="replace")
    assert [r["status"] for r in read_session(session)["runs"]] == ["completed", "completed"]


@pytest.mark.integration
@pytest.mark.parametrize("pause_first", [True, False])
def test_a_second_ctrl_c_ends_the_session_resumably(tmp_path: Path, pause_first: bool) -> None:
    """Paused (after the first Ctrl-C), the second ends the session there; before the pause took effect, it
    aborts the record at once. Either way: exit code 1 and the resume hint."""
    proc, session, _ = start_tiny(tmp_path)
    out = Output(proc)
    proc.send_signal(signal.SIGINT)
    if pause_first:
        out.wait_for(b"press Enter to resume")
    else:
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=120) == 1, out.join().decode(errors="replace")
    runs = read_session(session)["runs"]
    assert [r["status"] for r in runs] == (["completed"] if pause_first else ["aborted"])
    assert b"rig run --resume" in out.join()


@pytest.mark.integration
def test_the_emulator_rig_started_ends_when_rig_is_killed(tmp_path: Path) -> None:
    """``kill -9`` of rig mid-record: the emulator it started sees its parent gone and stops (within its parent
    poll and its shutdown), leaving no process holding the port."""
    proc, _, _ = start_tiny(tmp_path)
    emulator = child_of(proc, b"sim_table")
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + 30
    while running(emulator, b"sim_table"):
        assert time.monotonic() < deadline, "the emulator outlived rig"
        time.sleep(0.1)


@pytest.mark.parametrize(("edit", "where"), [
    (lambda text: text.replace('angles_deg = [0]', 'angles_deg = [12]'), "tiny.toml:2: angles_deg"),
    (lambda text: text.replace('KOBE/NIS000', 'KOBE/NOPE'), "tiny.toml:5: records[2]"),
    (lambda text: text.replace('table5 = 5', 'table5 = "five"'), "tiny.toml:16: bodies[1].table5"),
])
def test_bad_sequences_are_refused_before_the_table_is_contacted(tmp_path: Path, edit: object, where: str) -> None:
    """In-process: the conftest's guard fails the test if anything opens a socket."""
    (tmp_path / "tiny.toml").write_text(edit(TINY))  # type: ignore[operator]
    done = rig("run", "tiny.toml", "--table", "mavlink://127.0.0.1:9", "--yes", "-o", "s.h5", cwd=tmp_path)
    assert done.exit_code == 2, done.output
    assert where in done.stderr, done.stderr
    assert not (tmp_path / "s.h5").exists()  # nothing written, nothing contacted


FILE_LIMIT = 150_000
"""RLIMIT_FSIZE of the first full-disk test [bytes]: the session file is created, the first run's transaction finds
no room (EFBIG, as ENOSPC on a full disk: the same path through HDF5's file object)."""

FILE_LIMIT_MID_RUN = 400_000
"""RLIMIT_FSIZE of the second [bytes]: the first run begins, its writer finds no room mid-record."""


def rig_on_a_full_disk(tmp_path: Path, limit: int) -> tuple[subprocess.CompletedProcess[str], Path]:
    """``rig run`` of the tiny sequence whose files cannot grow beyond ``limit`` bytes (a write beyond fails as on
    a full disk: SIGXFSZ ignored)."""

    def limited() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)

    (tmp_path / "tiny.toml").write_text(TINY)
    session = tmp_path / "s.h5"
    done = subprocess.run([*RIG, "run", "tiny.toml", "--emulate", "--speed", "max", "--yes", "-o", str(session)],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300, preexec_fn=limited,
                          env={**os.environ, "COLUMNS": "160"})
    return done, session


@pytest.mark.integration
def test_a_full_disk_ends_the_session_saying_so_and_changes_nothing(tmp_path: Path) -> None:
    """``rig run`` whose session file cannot grow beyond 150 kB (issue 25: on a small tmpfs every run ended in a
    segmentation fault blaming the table): exit 1 with ``disk full: …``, no crash, the file as it was before the
    write that failed, and plain h5py opens it."""
    done, session = rig_on_a_full_disk(tmp_path, FILE_LIMIT)
    assert done.returncode == 1, done.stderr[-2000:] + done.stdout[-2000:]
    assert "faulted: disk full: " in done.stdout and "table:" not in done.stdout
    assert "Traceback" not in done.stderr
    assert session.stat().st_size <= FILE_LIMIT
    with h5py.File(session, "r") as h5:  # closed cleanly: plain h5py opens it
        assert len(h5["runs"]) == 0
    assert read_session(session)["runs"] == []


@pytest.mark.integration
def test_a_disk_full_mid_run_stops_the_table_and_keeps_the_rows_written(tmp_path: Path) -> None:
    """The writer finds no room mid-record: exit 1 with ``disk full: …`` (not a crash, not the table), the rows
    written before are in the file, and ``rig sessions recover`` marks the run interrupted keeping them all."""
    done, session = rig_on_a_full_disk(tmp_path, FILE_LIMIT_MID_RUN)
    assert done.returncode == 1, done.stderr[-2000:] + done.stdout[-2000:]
    assert "faulted: disk full: " in done.stdout and "table:" not in done.stdout
    (cut,) = read_session(session)["runs"]
    kept = cut["accel"]["0"]
    assert len(kept) > 100
    recovered = rig("sessions", "recover", str(session), cwd=tmp_path)
    assert recovered.exit_code == 0, recovered.stderr + recovered.stdout
    (after,) = read_session(session)["runs"]
    assert after["status"] == "interrupted"
    np.testing.assert_array_equal(after["accel"]["0"], kept)
