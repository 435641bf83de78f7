"""What every table transport must show when it streams a prepared drive to the emulator (issue 4's checks),
and the trajectories the transport tests share. A plain module, imported by the transport tests."""

from __future__ import annotations

import dataclasses
import itertools
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from drivers.controller import StreamReport, Subscription, TableError, TableStatus, TiltBatch, open_table
from rig.drive import Drive, prepare_drive
from rig.emulator import EmulatorProcess
from rig.records import load_record
from sim_table.process import TILT_RATE, parse_body
from sim_table.specimens import LYING, OVERTURN_MARGIN

TAU = 0.005  # the emulator's default leg lag [s]
POSE_NOISE = 2e-5  # leg reading noise (1 µm) through the kinematics, float32 on the wire, interpolation [m, rad]
SLENDER, STOCKY = "0.05x0.50@0.4,0", "0.15x0.45@-0.4,0"
WAIT = 10.0
"""Upper bound [s] on waiting for telemetry that must come (never reached when it works)."""


def drive_excerpt() -> Drive:
    """The first 6 s of NORTHR/MUL009 prepared at β = 2° (0.5 Hz corner, 0.5 s holds): a 16.4 s drive."""
    motion = load_record("fema:NORTHR/MUL009")
    cut = dataclasses.replace(motion, acc_h=motion.acc_h[:round(6.0 / motion.dt)])
    return prepare_drive(cut, angle=math.radians(2), settle=0.5, corner=0.5)


def surge(duration: float, function: Any) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(round(duration * 1000) + 1) * 1e-3
    poses = np.zeros((len(t), 6))
    poses[:, 0] = function(t)
    return t, poses


def smooth_ramp(t: np.ndarray, distance: float, duration: float) -> np.ndarray:
    tau = np.clip(t / duration, 0, 1)
    return distance * tau**3 * (10 - 15 * tau + 6 * tau**2)


def there_and_back(duration: float) -> tuple[np.ndarray, np.ndarray]:
    """A surge of 20 mm out and back in ``duration`` s at 1 kHz (ends where it began)."""
    half = duration / 2
    return surge(duration, lambda t: smooth_ramp(t, 0.02, half) - smooth_ramp(t - half, 0.02, half))


def assert_pose_follows(drive: Drive, report: StreamReport, statuses: list[TableStatus], pose_noise: float) -> None:
    """The achieved pose of the statuses inside the stream follows the command within the actuators' lag:
    |error| <= τ·max|v| over the last 50 ms + ``pose_noise`` [m, rad], and the lag is visible."""
    during = [s for s in statuses if report.t_start_ns <= s.t_ns <= report.t_end_ns]
    assert len(during) >= 0.95 * report.duration * 50  # 50 Hz status
    times = np.array([s.t_ns for s in during])
    achieved = np.array([s.pose for s in during])
    k = (times - report.t_start_ns) / round(1e9 / drive.rate)
    commanded = np.column_stack([np.interp(k, np.arange(len(drive.t)), drive.poses[:, j]) for j in range(6)])
    speed = np.abs(drive.velocities)
    window = np.array([speed[max(0, int(i) - 50):int(i) + 2].max(axis=0) for i in k])
    error = np.abs(achieved - commanded)
    assert np.all(error <= TAU * window * 1.02 + pose_noise), (error - TAU * window).max(axis=0)
    assert error.max(axis=0)[0] <= TAU * speed[:, 0].max() + pose_noise  # the headline: v_max·τ + noise
    assert error.max(axis=0)[0] > 0.2 * TAU * speed[:, 0].max()  # the lag is there


def assert_played_through(drive: Drive, report: StreamReport, progress: list[tuple[int, int]],
                          counters: dict[str, Any], wall: float) -> None:
    """The stream of ``drive`` played to its end on time, with no fault; its progress reports came at 10 Hz or more
    while chunks went out (over the ``wall`` time [s] the stream took, at most its duration — in virtual time it takes
    less —, less the lead), in order, the last one complete."""
    assert report.final is not None and report.final.state == "armed" and report.final.faults == ()
    assert report.underruns == 0 and counters["underruns"] == 0 and counters["samples_late"] == 0
    assert progress[-1] == (len(drive.t), len(drive.t))
    # 10 Hz while chunks go out: from the start for the drive's duration (the wall time, if shorter), less the
    # lead at the end — the last chunk goes out that far ahead of its time, and the stream then only waits
    assert len(progress) >= math.floor(10 * max(min(report.duration, wall) - report.lead, 0.0))
    assert all(a[0] <= b[0] for a, b in itertools.pairwise(progress))


def assert_resting_force(drive: Drive, report: StreamReport, sample_times: np.ndarray, force: np.ndarray) -> None:
    """An accelerometer's specific force over the last 0.4 s of the drive's leading hold, resting at the tilt β:
    (−g sin β, 0, g cos β) within 0.01 m/s²."""
    hold = (sample_times >= report.t_start_ns + round((drive.motion[0] - 0.4) * 1e9)) & (
        sample_times <= report.t_start_ns + round(drive.motion[0] * 1e9))  # resting at the tilt
    beta = drive.angle
    np.testing.assert_allclose(force[hold].mean(axis=0), [-9.81 * math.sin(beta), 0, 9.81 * math.cos(beta)],
                               atol=0.01)


def assert_overturns_reported_once(found: list[Any], stats: dict[str, Any], counters: dict[str, Any]) -> None:
    """The detections ``found`` are the emulator's overturns, in order, each once although every event came 4
    times; the slender body (0) is among them."""
    assert [(d.event_id, d.body_id, d.direction) for d in found] == [
        (o["event_id"], o["body_id"], o["direction"]) for o in counters["overturns"]]
    assert 0 in {d.body_id for d in found}  # the slender body fell
    assert stats["duplicate_detections"] == 3 * len(found)
    assert counters["link"]["overturn_messages_sent"] == 4 * len(found)


def collect_tilts(tilts: Subscription[TiltBatch], bodies: int, until_ns: int) -> list[TiltBatch]:
    """The tilt batches received, waiting (up to :data:`WAIT`) until each of the first ``bodies`` bodies has a sample
    at or after controller time ``until_ns`` (a batch is sent when full: up to 59 samples, 295 ms, on MAVLink)."""
    batches: list[TiltBatch] = []
    deadline = time.monotonic() + WAIT
    while True:
        batches += tilts.drain()
        last = {b.body_id: int(b.times_ns()[-1]) for b in batches}
        if all(last.get(body, -1) >= until_ns for body in range(bodies)) or time.monotonic() > deadline:
            return batches
        time.sleep(0.05)


def assert_tilts(drive: Drive, report: StreamReport, batches: list[TiltBatch], bodies: list[str],
                 overturns: list[dict[str, Any]]) -> None:
    """Each of ``bodies`` (``--body`` texts) reported its tilt: batches in sequence, samples every 1/TILT_RATE on the
    grid of controller time, contiguous from batch to batch, every grid time of the stream once. The angle is
    relative to the plate: ~0 while the body rests on the tilted plate (the drive's leading hold). A body among the
    emulator's ``overturns`` stayed within its detection threshold (α + margin) before its overturn and is past it,
    in its direction, at the first sample after; any other stayed within it."""
    spacing = round(1e9 / TILT_RATE)
    assert {b.body_id for b in batches} == set(range(len(bodies)))
    for body_id, text in enumerate(bodies):
        mine = [b for b in batches if b.body_id == body_id]
        assert [b.seq for b in mine] == list(range(mine[0].seq, mine[0].seq + len(mine)))
        times = np.concatenate([b.times_ns() for b in mine])
        angles = np.concatenate([b.angles for b in mine])
        assert times[0] % spacing == 0 and np.all(np.diff(times) == spacing)
        inside = (times >= report.t_start_ns) & (times <= report.t_end_ns)
        assert inside.sum() == report.t_end_ns // spacing - math.ceil(report.t_start_ns / spacing) + 1
        hold = (times >= report.t_start_ns + round((drive.motion[0] - 0.4) * 1e9)) & (
            times <= report.t_start_ns + round(drive.motion[0] * 1e9))  # resting at the tilt
        assert hold.sum() >= 0.4 * TILT_RATE and np.abs(angles[hold]).max() < 1e-3
        threshold = min(parse_body(text).body.alpha + OVERTURN_MARGIN, LYING)
        fell = [o for o in overturns if o["body_id"] == body_id]
        if fell:
            t_fall = round(fell[0]["t"] * 1e9)
            assert np.abs(angles[times < t_fall]).max() < threshold
            assert fell[0]["direction"] * angles[times >= t_fall][0] >= threshold
        else:
            assert np.abs(angles).max() < threshold


def stream_and_check(drive: Drive, listen: str, key_file: Path, samples_per_chunk: int,
                     controller_type: type, speed: str = "max") -> dict[str, Any]:
    """Stream ``drive`` through the transport of ``listen`` to an emulator at ``speed`` (default: virtual time)
    with a slender and a stocky body and two accelerometers; assert the issue's checks (and the bodies' tilt
    telemetry); return the emulator's counters for transport checks."""
    emulator = EmulatorProcess.start(listen, "--body", SLENDER, "--body", STOCKY, "--accel", "0,0,0",
                                     "--accel", "1.0,-0.5,0", "--speed", speed, key_file=key_file)
    link_error: TableError | None = None
    try:
        with open_table(emulator.url, key_file=str(key_file)) as table:
            assert isinstance(table, controller_type)
            statuses, accel, detections = table.statuses(), table.accelerations(), table.detections()
            tilts = table.tilts()
            table.arm()
            progress: list[tuple[int, int]] = []
            started = time.monotonic()
            report: StreamReport = table.stream(drive.t, drive.poses,  # the default lead (1 s), as a lab plays
                                                on_progress=lambda *p: progress.append(p))
            wall = time.monotonic() - started
            time.sleep(0.6)  # the last overturn event's repetitions (3 × 100 ms)
            tilt_batches = collect_tilts(tilts, 2, report.t_end_ns)
            stats = table.link_stats()
    except TableError as exc:  # the host's view: add the emulator's (did it stall, or the host?)
        link_error = exc
    finally:
        counters = emulator.stop()
    if link_error is not None:
        raise AssertionError(f"{link_error}\nthe emulator's timing: {counters['timing']}\n"
                             f"its link counters: {counters['link']}") from link_error
    assert_played_through(drive, report, progress, counters, wall)
    assert counters["chunk_margin_min_ns"] > 0 and counters["chunks_missing"] == 0
    assert report.chunks == counters["chunks_accepted"] == math.ceil(len(drive.t) / samples_per_chunk)
    spacing = round(1e9 / drive.rate)

    assert_pose_follows(drive, report, statuses.drain(), POSE_NOISE)

    # every accelerometer sample once, in order, contiguous: count = duration × rate, for each sensor
    received = accel.drain()
    gaps = {sensor: [(a.seq, b.seq) for a, b in itertools.pairwise(x for x in received if x.sensor_id == sensor)
                     if b.seq != a.seq + 1] for sensor in (0, 1)}
    assert stats["accel_batches_lost"] == 0, f"accelerometer batches lost between (seq, seq): {gaps}"
    assert {b.sensor_id for b in received} == {0, 1}
    for sensor in (0, 1):
        batches = [b for b in received if b.sensor_id == sensor]
        assert [b.seq for b in batches] == list(range(batches[0].seq, batches[0].seq + len(batches)))
        sample_times = np.concatenate([b.times_ns() for b in batches])
        assert np.all(np.diff(sample_times) == spacing)
        inside = (sample_times >= report.t_start_ns) & (sample_times <= report.t_end_ns)
        assert inside.sum() == report.t_end_ns // spacing - math.ceil(report.t_start_ns / spacing) + 1
        assert_resting_force(drive, report, sample_times, np.concatenate([b.samples for b in batches]))

    # overturns: reported once each although every event came 4 times
    found = detections.drain()
    assert_overturns_reported_once(found, stats, counters)
    assert [d.t_ns for d in found] == [round(o["t"] * 1e9) for o in counters["overturns"]]
    assert len({d.event_id for d in found}) == len(found) == len({d.body_id for d in found})

    # the bodies' tilt: every sample once, in order, and physically right (the overturns checked against it)
    assert stats["tilt_batches_lost"] == 0 and len(tilt_batches) <= counters["link"]["tilt_batches_sent"]
    assert_tilts(drive, report, tilt_batches, [SLENDER, STOCKY], counters["overturns"])
    return counters
