"""The run recorder and the limit detectors: a trip is acted on (the orchestrator's callback) before it is written,
then written as the run's event at the crossing's time and put into the live tap for the console; the first status
showing the table stopped gives the latency in table time. The table is a real feedback hub fed by the test; the
run log a real session file."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from analysis.table.controller_limits import ControllerLevel, ControllerTrip
from analysis.table.limit_detectors import Detector, LimitDetectors
from drivers.controller import AccelBatch, ControllerText, FaultSource, TableStatus
from protocols.canopen.od import EMCY_FOLLOWING_ERROR
from rig.orchestrator.limits import LimitWatch, Trip
from rig.orchestrator.live import LiveTap
from rig.orchestrator.recorder import RunRecorder
from rig.orchestrator.states import Progress
from rig.session import SessionLog, read_session
from tests.helpers.feedback import FeedbackTable

SPACING_NS = 1_000_000
"""1 kHz accelerometer samples."""



class CountingLog:
    """A run log that counts the events written through it (and writes them)."""

    def __init__(self, run_log: Any) -> None:
        self.run_log = run_log
        self.events = 0

    def __getattr__(self, name: str) -> Any:
        return getattr(self.run_log, name)

    def add_event(self, t: float, text: str) -> None:
        self.events += 1
        self.run_log.add_event(t, text)


def status(t_ns: int, state: str) -> TableStatus:
    return TableStatus(t_ns, state, 0, 0, 0, (), 0, np.zeros(6), 0)


def test_a_trip_is_acted_on_written_shown_and_its_stop_timed(tmp_path: Path) -> None:
    table = FeedbackTable()
    log = SessionLog.create(tmp_path / "s.h5", rig_config={"test": True}, sequence={"name": "limits"},
                            software_version="test")
    run_log = CountingLog(log.begin_run(0, record="r", scale_factor=1.0, angle_deg=0.0, commanded=np.zeros((2, 7)),
                                        bodies=[], sensors=["0"]))
    acted: list[tuple[Trip, int]] = []
    live = LiveTap()
    limits = LimitWatch(LimitDetectors((Detector("accel.x", warn_high=2.0, abort_high=4.0, persistence=2),)))
    recorder = RunRecorder(table, run_log, {0: "0"}, [], Progress(runs_total=1), live=live,  # type: ignore[arg-type]
                           limits=limits, on_trip=lambda trip: acted.append((trip, run_log.events)))
    recorder.start(0)
    x = np.array([0.0, 3.0, 5.0, 0.0, 5.0, 6.0, 7.0, 0.0])  # a single sample past abort: no trip; two in a row: trip
    samples = np.column_stack([x, np.zeros_like(x), np.full_like(x, 9.81)])
    table.feedback.publish_accel(AccelBatch(0, 0, 0, SPACING_NS, samples))
    table.feedback.publish_status(status(8_000_000, "streaming"))
    table.feedback.publish_status(status(17_000_000, "stopping"))
    recorder.finish(0.2)
    run_log.end("aborted", reason="limit accel.0.x")
    log.close()
    assert [(trip.level, trip.t, trip.value, trip.action) for trip, _ in acted] == [
        ("warn_high", 0.002, 5.0, "record"), ("abort_high", 0.005, 6.0, "controlled_stop")]
    assert [written for _, written in acted] == [0, 0]  # acted on before anything was written
    assert recorder.stop_latency is not None and abs(recorder.stop_latency - 0.012) < 1e-9
    (run,) = read_session(tmp_path / "s.h5")["runs"]
    assert [(event["t"], event["text"]) for event in run["events"]] == [
        (0.002, "limit accel.0.x: 5 m/s² past warn high 2 m/s²: record (host)"),
        (0.005, "limit accel.0.x: 6 m/s² past abort high 4 m/s²: controlled_stop (host)"),
        (0.017, "limit accel.0.x: the table was stopping 12.0 ms after the crossing (table time; tripped by the host)")]
    assert [item for item in live.drain() if item[0] == "fault"] == [
        ("fault", 0.002, "limit accel.0.x", "limit accel.0.x: 5 m/s² past warn high 2 m/s²: record (host)"),
        ("fault", 0.005, "limit accel.0.x", "limit accel.0.x: 6 m/s² past abort high 4 m/s²: controlled_stop (host)")]



def test_the_controller_s_own_trips_limits_and_warnings_are_recorded_marked_controller(tmp_path: Path) -> None:
    table = FeedbackTable()
    log = SessionLog.create(tmp_path / "s.h5", rig_config={"test": True}, sequence={"name": "limits"},
                            software_version="test")
    run_log = log.begin_run(0, record="r", scale_factor=1.0, angle_deg=0.0, commanded=np.zeros((2, 7)), bodies=[],
                            sensors=["front"])
    acted: list[Trip] = []
    limits = LimitWatch(LimitDetectors((Detector("accel.x", abort_high=4.0),)))
    recorder = RunRecorder(table, run_log, {0: "front"}, [], Progress(runs_total=1),  # type: ignore[arg-type]
                           limits=limits, on_trip=acted.append)
    recorder.start(0)
    level = ControllerLevel("accel.x", "abort_high", 4.0, 1, "controlled_stop")
    trip = ControllerTrip(5_000_000, 0, 6.0, level)
    table.feedback.publish_limit_trip(trip)
    table.feedback.publish_limit_trip(trip)  # the controller repeats it: kept once
    table.feedback.publish_status(status(1_000_000, "streaming"))
    table.feedback.publish_status(replace(status(7_000_000, "stopping"), faults=("STROKE",)))
    table.feedback.publish_status(replace(status(9_000_000, "faulted"), faults=("STROKE", "DRIVE")),
                                  sources=(FaultSource(2, EMCY_FOLLOWING_ERROR),))
    table.feedback.publish_controller_text(ControllerText(0, "ERROR", "leg 2 drive: following error"))
    table.feedback.publish_controller_text(ControllerText(0, "INFO", "drives enabled"))  # not a warning: not kept
    recorder.finish(0.2)
    run_log.end("aborted", reason="limit accel.front.x")
    log.close()
    assert [(t.channel, t.source) for t in acted] == [("accel.front.x", "controller")]  # acted on as the host's
    assert recorder.stop_latency is not None and abs(recorder.stop_latency - 0.002) < 1e-9
    (run,) = read_session(tmp_path / "s.h5")["runs"]
    [said] = [event for event in run["events"] if event["text"].startswith("controller ")]
    assert (said["t"], said["text"]) == (pytest.approx(0.009),
                                         "controller ERROR: leg 2 drive: following error (controller)")
    assert [(pytest.approx(event["t"]), event["text"]) for event in run["events"] if event is not said] == [
        (0.005, "limit accel.front.x: 6 m/s² past abort high 4 m/s²: controlled_stop (controller)"),
        (0.007, "limit accel.front.x: the table was stopping 2.0 ms after the crossing (table time; tripped by the "
                "controller)"),
        (0.007, "limit leg.stroke: past the controller's limit (a leg's command reached its stroke): "
                "controlled_stop (controller)"),
        (0.009, "limit leg.2.following_error: past the controller's limit (EMCY 0x8611 following error): "
                "controlled_stop (controller)")]


def test_a_controller_trip_that_comes_after_the_stopping_status_is_still_timed(tmp_path: Path) -> None:
    """zenoh does not order its keys: the host's trip and the status showing the stop may come before the
    controller's trip of the same crossing (published last here; the recorder may drain the three together): each
    source's trip is timed once, and the controller's is the latency."""
    table = FeedbackTable()
    log = SessionLog.create(tmp_path / "s.h5", rig_config={"test": True}, sequence={"name": "limits"},
                            software_version="test")
    run_log = log.begin_run(0, record="r", scale_factor=1.0, angle_deg=0.0, commanded=np.zeros((2, 7)), bodies=[],
                            sensors=["0"])
    recorder = RunRecorder(table, run_log, {0: "0"}, [], Progress(runs_total=1),  # type: ignore[arg-type]
                           limits=LimitWatch(LimitDetectors((Detector("accel.x", abort_high=4.0),))))
    recorder.start(0)
    x = np.array([0.0, 0.0, 5.0, 6.0])
    table.feedback.publish_accel(AccelBatch(0, 0, 0, SPACING_NS, np.column_stack([x, 0 * x, 0 * x + 9.81])))
    table.feedback.publish_status(status(6_000_000, "stopping"))
    level = ControllerLevel("accel.x", "abort_high", 4.0, 1, "controlled_stop")
    table.feedback.publish_limit_trip(ControllerTrip(2_000_000, 0, 5.0, level))
    recorder.finish(0.2)
    run_log.end("aborted", reason="limit accel.0.x")
    log.close()
    assert recorder.stop_latency is not None and abs(recorder.stop_latency - 0.004) < 1e-9
    (run,) = read_session(tmp_path / "s.h5")["runs"]
    timed = sorted(event["text"] for event in run["events"] if "after the crossing" in event["text"])
    assert timed == ["limit accel.0.x: the table was stopping 4.0 ms after the crossing (table time; tripped by the "
                     "controller)",
                     "limit accel.0.x: the table was stopping 4.0 ms after the crossing (table time; tripped by the "
                     "host)"]


def test_a_silent_link_trips_link_age_from_the_recorder_s_own_loop(tmp_path: Path) -> None:
    """One status, then none: no sample arrives, yet the recorder's loop (which wakes at least every
    ``POLL_SECONDS``) samples the link's age every 10 ms of host time, and the abort level is acted on once, at the
    second sample past it (persistence 2), however late the loop looked."""
    table = FeedbackTable()
    log = SessionLog.create(tmp_path / "s.h5", rig_config={"test": True}, sequence={"name": "limits"},
                            software_version="test")
    run_log = log.begin_run(0, record="r", scale_factor=1.0, angle_deg=0.0, commanded=np.zeros((2, 7)), bodies=[],
                            sensors=[])
    acted: list[Trip] = []
    limits = LimitWatch(LimitDetectors((Detector("link.age", abort_high=0.05, persistence=2),)))
    recorder = RunRecorder(table, run_log, {}, [], Progress(runs_total=1),  # type: ignore[arg-type]
                           limits=limits, on_trip=acted.append)
    recorder.start(0)
    table.feedback.publish_status(replace(status(1_000_000, "streaming"), host_ns=time.monotonic_ns()))
    recorder.finish(0.3)  # the link stays silent for at least this long
    run_log.end("aborted", reason="limit link.age")
    log.close()
    [trip] = acted
    assert (trip.channel, trip.level, trip.action, trip.source) == ("link.age", "abort_high", "controlled_stop", "host")
    assert 0.05 < trip.value < 0.08 and trip.t == pytest.approx(0.001 + trip.value)
    (run,) = read_session(tmp_path / "s.h5")["runs"]
    assert [event["text"] for event in run["events"]] == [trip.text()]
