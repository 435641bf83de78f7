"""The run recorder waits for the accelerometers' last samples instead of a fixed linger, and says what never came.

The table here is the real feedback hub a backend's receive thread publishes into (`drivers.controller.Feedback`),
fed by the test; the run log is a real session file.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np

from drivers.controller import AccelBatch, StreamReport, TableStatus
from rig.orchestrator.orchestrator import degradations, missing_tail
from rig.orchestrator.recorder import RunRecorder
from rig.orchestrator.states import Progress
from rig.session import SessionLog, read_session
from tests.helpers.feedback import FeedbackTable as FeedbackHub

SPACING_NS = 1_000_000
"""1 kHz accelerometer samples."""

PER_BATCH = 19
"""Samples per batch, as MAVLink sends them."""


class FeedbackTable(FeedbackHub):
    """The feedback hub; the recorder stops the table only when a write failed, which these tests never cause."""

    def stop(self) -> None:
        raise AssertionError("the recorder stopped the table: a write failed")



def batches(first: int, last: int) -> list[AccelBatch]:
    """Batches of sensor 0 holding samples ``first`` … ``last`` (1 kHz from t = 0, :data:`PER_BATCH` a batch,
    the last one shorter), each sample's x equal to its index."""
    out = []
    for seq, start in enumerate(range(first, last + 1, PER_BATCH)):
        index = np.arange(start, min(start + PER_BATCH, last + 1))
        samples = np.column_stack([index, np.zeros_like(index), np.full(len(index), 9.81)]).astype(float)
        out.append(AccelBatch(0, seq, start * SPACING_NS, SPACING_NS, samples))
    return out


def recording(tmp_path: Path, sensors: dict[int, str]) -> tuple[FeedbackTable, RunRecorder, SessionLog, object]:
    table = FeedbackTable()
    log = SessionLog.create(tmp_path / "s.h5", rig_config={"test": True}, sequence={"name": "recorder"},
                            software_version="test")
    run_log = log.begin_run(0, record="r", scale_factor=1.0, angle_deg=0.0, commanded=np.zeros((2, 7)), bodies=[],
                            sensors=list(sensors.values()))
    recorder = RunRecorder(table, run_log, sensors, [], Progress(runs_total=1))  # type: ignore[arg-type]
    recorder.start(0)
    return table, recorder, log, run_log


def test_the_last_batch_coming_after_the_linger_is_still_recorded(tmp_path: Path) -> None:
    """The drive ends at 2.000 s; its last 19 samples come 0.3 s after the 0.05 s linger (a busy host or controller):
    the recorder waits for them, and the run holds every sample through 2.000 s."""
    table, recorder, log, run_log = recording(tmp_path, {0: "plate"})
    *early, tail = batches(0, 2000)
    for batch in early:
        table.feedback.publish_accel(batch)
    late = threading.Timer(0.3, table.feedback.publish_accel, args=(tail,))
    late.start()
    recorder.finish(0.05, until=2.0, wait=60.0)  # the bound only matters if the tail never comes
    late.join()
    assert recorder.short_of(2.0) == {}
    run_log.end("completed")
    log.close()
    (run,) = read_session(tmp_path / "s.h5")["runs"]
    t = run["accel"]["plate"][:, 0]
    assert len(t) == 2001 and t[-1] == 2.0


def test_samples_that_never_reach_the_drive_s_end_are_named_and_degrade_the_run(tmp_path: Path) -> None:
    """Sensor 0's samples stop 19 ms before the end, sensor 1 sends none: after the wait both are named, with where
    the samples end, and the run is degraded for it."""
    table, recorder, log, run_log = recording(tmp_path, {0: "plate", 1: "corner"})
    for batch in batches(0, 1981):
        table.feedback.publish_accel(batch)
    recorder.finish(0.0, until=2.0, wait=0.1)
    short = recorder.short_of(2.0)
    assert short == {"plate": 1.981, "corner": None}
    assert missing_tail(short, 2.0) == ["accelerometer plate: samples end at 1.981 s, 0.019 s before the drive's end",
                                        "accelerometer corner: no samples"]
    run_log.end("completed")
    log.close()


def test_the_samples_through_the_drive_s_end_less_one_sample_are_complete(tmp_path: Path) -> None:
    """One sample short of the end is within the sampling: not missing (the accelerometer's grid need not hit the
    drive's last instant)."""
    table, recorder, log, run_log = recording(tmp_path, {0: "plate"})
    for batch in batches(0, 1999):
        table.feedback.publish_accel(batch)
    recorder.finish(0.0, until=2.0, wait=0.0)
    assert recorder.short_of(2.0) == {}
    assert recorder.short_of(2.0011) == {"plate": 1.999}
    run_log.end("completed")
    log.close()


def test_a_missing_tail_is_a_degradation() -> None:
    """A run that played to its end with nothing else wrong is degraded by an accelerometer that stopped short."""
    status = TableStatus(t_ns=0, state="armed", buffer_depth=0, last_chunk_seq=0, underruns=0, faults=(),
                         refused_commands=0, pose=np.zeros(6), host_ns=0)
    report = StreamReport(chunks=250, samples=2001, underruns=0, t_start_ns=0, t_end_ns=2_000_000_000, lead=1.0,
                          send_lateness_ns=np.zeros(250, dtype=np.int64), final=status)
    assert degradations(status, report, 0, (), {}, 2.0) == []
    assert degradations(status, report, 0, (), {"plate": None}, 2.0) == ["accelerometer plate: no samples"]
