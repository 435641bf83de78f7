"""Benchmark: sustained logging rate of the session writer (`rig.session`) and the data at risk on a crash.

Prints one JSON object:

* ``figure``/``value``/``unit``: samples per second the session writer takes in *and* gets onto disk, pushing
  as fast as it accepts them for ``--seconds`` with ``--channels`` accelerometers plus the commanded stream
  (`RunLog.append_commanded`). One sample = one row of one stream: a (t, ax, ay, az) row of one
  accelerometer, or a (t, surge, …, yaw) row of the commanded stream. The time runs from the first append to
  the end of `RunLog.end` (everything flushed, file closed, final attributes committed);
* ``compared_with``: the real-time requirement (``channels`` × 1 kHz plus the 1 kHz commanded stream), the
  issue's target of 1,000,000 samples/s, and plain h5py appending the same rows to a file without SWMR, queue
  or thread (measured in the same run);
* ``data_at_risk_s``: the largest time between a sample's append and the end of the flush that put it on
  disk (what a ``kill -9`` can lose), with the producer paced by the clock at the real-time rate and at the
  1,000,000 samples/s target, and unpaced (saturated: then it is the queue's length in time);
* append latency (the producer's cost per call), begin/end durations, file size, and how late a 1 kHz
  sleep-paced thread in the same process runs while the writer logs in real time (vs. alone, same run).

* ``while_streaming``: a drive streamed at 1 kHz over MAVLink to the emulator (its own process, loopback) with
  the writer saturated by the same process meanwhile, against the same drive streamed without it (same run):
  the emulator's setpoint underruns, the setpoint sender's lateness, and the logging rate achieved meanwhile.

* ``checksum_cost_per_flush``: the writer's mean time per flush [ms] with the run's checksum table
  (`rig.session.checksums`: a CRC-32 per block, appended in the next flush) and without it, the same rows paced at
  the 1,000,000 samples/s target (same run), and the part of it spent on the checksums.

Usage: ``python benchmarks/session_logging.py [--seconds 5] [--channels 8] [--stream-seconds 20] [--dir DIR]``.
`measure_writer` is importable for benchmarks that stream to the emulator at the same time.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

import h5py
import numpy as np

from protocols.signing_key import write_signing_key
from rig.session import SessionLog, layout, schema
from rig.session.hdf5props import LIBVER
from rig.session.writer import BlockWriter

TARGET = 1_000_000.0  # [samples/s] the target
RATE = 1000.0  # [Hz] real-time rate of each accelerometer and of the commanded stream
BODIES = [{"body_id": 1, "b": 0.1, "h": 0.5, "depth": 0.1, "mass": 4.0, "x": 0.0, "y": 0.0}]


def _begin(log: SessionLog, channels: int) -> object:
    return log.begin_run(0, record="benchmark", scale_factor=1.0, angle_deg=0.0, commanded=np.zeros((0, 7)),
                         bodies=BODIES, sensors=[f"acc{i}" for i in range(channels)])


class _PacingProbe(threading.Thread):
    """A 1 kHz loop paced by ``time.sleep`` to absolute deadlines (like the setpoint sender): its lateness [ms]
    shows how long other threads of the process (the session writer inside h5py) keep it from running."""

    def __init__(self) -> None:
        super().__init__(daemon=True)
        self.late_ms: list[float] = []
        self._stop_event = threading.Event()

    def run(self) -> None:
        period, next_t = 1e-3, time.perf_counter()
        while not self._stop_event.is_set():
            next_t += period
            time.sleep(max(0.0, next_t - time.perf_counter()))
            self.late_ms.append((time.perf_counter() - next_t) * 1e3)

    def stop(self) -> dict:
        self._stop_event.set()
        self.join()
        late = np.array(self.late_ms[10:])
        return {"p50": float(np.percentile(late, 50)), "p99": float(np.percentile(late, 99)),
                "max": float(late.max())}


def measure_writer(seconds: float, channels: int = 8, *, rate: float | None = None, block: int = 1000,
                   directory: str | None = None, max_queue_mb: float = 256.0, probe: bool = False) -> dict:
    """Push ``block`` rows per stream per round (``channels`` accelerometers + the commanded stream) into one run
    for ``seconds``: paced by the clock to ``rate`` samples/s in total, or (``rate=None``) as fast as the writer
    takes them, the producer pausing only while more than ``max_queue_mb`` MB are queued.

    Returns the rate achieved [samples/s] (first append to the end of `RunLog.end`: all on disk, committed),
    counts, the producer's append-call latency [µs], the writer's worst append-to-disk latency [s] (data at risk
    on a crash), its longest flush [s], begin/end durations [s] and the file size [MB]; with ``probe``, the
    lateness [ms] of a 1 kHz sleep-paced thread running meanwhile (`_PacingProbe`)."""
    with tempfile.TemporaryDirectory(dir=directory, prefix="sess_bench_") as tmp:
        path = Path(tmp) / "bench.h5"
        log = SessionLog.create(path, {"benchmark": True}, {}, "benchmark")
        t0 = time.perf_counter()
        run = _begin(log, channels)
        begin_s = time.perf_counter() - t0
        sensors = [f"acc{i}" for i in range(channels)]
        rng = np.random.default_rng(1)
        xyz = rng.normal(size=(block, 3))
        pose = rng.normal(size=(block, 6)) * 1e-3
        per_round = block * (channels + 1)
        cap = int(max_queue_mb * 1e6 / 40)  # rows (32-56 bytes each)
        calls: list[float] = []
        pushed = k = 0
        pacing = _PacingProbe() if probe else None
        if pacing is not None:
            pacing.start()
        start = time.perf_counter()
        deadline = start + seconds
        while (now := time.perf_counter()) < deadline:
            if rate is not None:
                time.sleep(max(0.0, start + pushed / rate - now))
            elif pushed - sum(run.stats.rows.values()) > cap:
                time.sleep(0.001)
                continue
            t = (np.arange(block) + k) / RATE
            for sensor in sensors:
                c0 = time.perf_counter()
                run.append_accel(sensor, t, xyz)
                calls.append(time.perf_counter() - c0)
            c0 = time.perf_counter()
            run.append_commanded(t, pose)
            calls.append(time.perf_counter() - c0)
            pushed += per_round
            k += block
        t_end = time.perf_counter()
        run.end("completed")
        done = time.perf_counter()
        pacing_late = pacing.stop() if pacing is not None else None
        stats = run.stats
        written = sum(stats.rows.values())
        log.close()
        size = path.stat().st_size
    calls_us = np.array(calls) * 1e6
    return {
        "samples_per_s": written / (done - start),
        "paced_at_samples_per_s": rate,
        "samples": written,
        "rows_per_stream": k,
        "channels": channels,
        "block_rows": block,
        "seconds": done - start,
        "megabytes_per_s": size / 1e6 / (done - start),
        "append_call_us": {"p50": float(np.percentile(calls_us, 50)), "p99": float(np.percentile(calls_us, 99)),
                           "max": float(calls_us.max())},
        "max_append_to_disk_s": stats.max_latency_s,
        "max_flush_s": stats.max_flush_s,
        "max_flush_gap_s": stats.max_flush_gap_s,
        "flushes": stats.flushes,
        "checksum_s": stats.checksum_s,
        "writer_busy_fraction": stats.busy_s / (done - start),
        "begin_run_s": begin_s,
        "end_s": done - t_end,
        "file_mb": size / 1e6,
        "pacing_probe_late_ms": pacing_late,
    }


def measure_flush_cost(seconds: float, channels: int = 8, *, checksummed: bool, rate: float = TARGET,
                       block: int = 1000, directory: str | None = None) -> dict:
    """One run's `BlockWriter` (SWMR, flushing every 0.25 s) fed ``block`` rows per stream per round, paced to
    ``rate`` samples/s in total for ``seconds``, with the run's checksum table or without it (``checksummed``).
    Returns the mean and largest time per flush [ms], the mean time per flush spent on checksums [ms] and the
    rows per flush."""
    sensors = [f"acc{i}" for i in range(channels)]
    body = np.array([(1, 0.1, 0.5, 0.1, 4.0, 0.0, 0.0, b"", np.nan, np.nan)], dtype=schema.BODY)
    with tempfile.TemporaryDirectory(dir=directory, prefix="sess_bench_") as tmp:
        path = Path(tmp) / "flush.h5"
        with h5py.File(path, "w", libver=LIBVER) as h5:
            layout.create_root(h5, software_version="benchmark", created=schema.iso_now(), rig_config="{}",
                               sequence="{}")
            layout.create_run(h5["runs"], "0001", plan_index=0, attempt=1, record="benchmark", scale_factor=1.0,
                              angle_deg=0.0, started=schema.iso_now(), commanded=np.zeros((0, 7)), bodies=body,
                              sensors=sensors, attrs={})
        h5 = h5py.File(path, "r+", libver=LIBVER, locking=False)
        h5.swmr_mode = True
        group = h5["runs/0001"]
        datasets = {"commanded": group["commanded"], **{f"accel/{s}": group["accel"][s] for s in sensors}}
        writer = BlockWriter(h5, datasets, 0.25, group["checksums"] if checksummed else None)
        rng = np.random.default_rng(1)
        xyz, pose = rng.normal(size=(block, 4)), rng.normal(size=(block, 7))
        writer.start()
        start = time.perf_counter()
        pushed = k = 0
        while (now := time.perf_counter()) < start + seconds:
            time.sleep(max(0.0, start + pushed / rate - now))
            for sensor in sensors:
                writer.put(f"accel/{sensor}", xyz)
            writer.put("commanded", pose)
            pushed += block * (channels + 1)
            k += block
        stats = writer.stop()
        h5.close()
    return {"checksummed": checksummed, "flushes": stats.flushes,
            "mean_flush_ms": round(stats.busy_s / stats.flushes * 1e3, 3),
            "max_flush_ms": round(stats.max_flush_s * 1e3, 3),
            "checksum_ms_per_flush": round(stats.checksum_s / stats.flushes * 1e3, 4),
            "rows_per_flush": round(sum(stats.rows.values()) / stats.flushes)}


def measure_pacing_alone(seconds: float) -> dict:
    """The `_PacingProbe` with nothing else running in the process (baseline) [ms late]."""
    pacing = _PacingProbe()
    pacing.start()
    time.sleep(seconds)
    return pacing.stop()


def measure_raw_h5py(seconds: float, channels: int = 8, *, block: int = 1000, directory: str | None = None) -> dict:
    """Baseline: plain h5py (no SWMR, no queue, no thread) appending the same rows to chunked datasets."""
    with tempfile.TemporaryDirectory(dir=directory, prefix="sess_bench_") as tmp, \
            h5py.File(Path(tmp) / "raw.h5", "w", libver="latest") as h5:
        sets = [h5.create_dataset(f"acc{i}", shape=(0, 4), maxshape=(None, 4), chunks=(4096, 4), dtype="<f8")
                for i in range(channels)]
        sets.append(h5.create_dataset("commanded", shape=(0, 7), maxshape=(None, 7), chunks=(2048, 7), dtype="<f8"))
        rows4 = np.random.default_rng(1).normal(size=(block, 4))
        rows7 = np.random.default_rng(2).normal(size=(block, 7))
        start = time.perf_counter()
        n = 0
        while time.perf_counter() - start < seconds:
            for ds in sets:
                ds.resize(n + block, axis=0)
                ds[n:] = rows7 if ds.shape[1] == 7 else rows4
            n += block
        h5.flush()
        elapsed = time.perf_counter() - start
    return {"samples_per_s": n * len(sets) / elapsed, "seconds": elapsed}


def measure_streaming(seconds: float, channels: int, *, logging: bool, directory: str | None = None) -> dict:
    """Stream a ``seconds`` long 1 kHz drive (a 0.5 Hz, 50 mm surge sine between quintic ramps) over MAVLink to
    the emulator; with ``logging``, `measure_writer` saturates a session writer in this process meanwhile. The
    emulator's underruns, the chunks' send lateness [ms] and, with logging, the writer's rate [samples/s]."""

    from drivers.controller import open_table
    from rig.emulator import EmulatorProcess

    t = np.arange(round(seconds * RATE) + 1) / RATE
    envelope = np.clip(np.minimum(t, t[-1] - t) / 1.0, 0.0, 1.0)
    poses = np.zeros((len(t), 6))
    poses[:, 0] = 0.05 * envelope**3 * (10 - 15 * envelope + 6 * envelope**2) * np.sin(2 * np.pi * 0.5 * t)
    with tempfile.TemporaryDirectory(prefix="sess_bench_key_") as tmp:
        key = Path(tmp) / "rig.key"
        write_signing_key(key)
        emulator = EmulatorProcess.start("mavlink://127.0.0.1:0", key_file=key)
        writer: dict = {}
        try:
            with open_table(emulator.url, key_file=str(key)) as table:
                table.arm()
                logger = None
                if logging:
                    logger = threading.Thread(target=lambda: writer.update(
                        measure_writer(seconds, channels, directory=directory)))
                    logger.start()
                report = table.stream(t, poses, lead=0.05)
                if logger is not None:
                    logger.join()
        finally:
            counters = emulator.stop()
    late_ms = report.send_lateness_ns * 1e-6
    return {"logging": logging, "underruns": counters["underruns"], "samples_late": counters["samples_late"],
            "send_late_p50_ms": round(float(np.percentile(late_ms, 50)), 3),
            "send_late_p99_ms": round(float(np.percentile(late_ms, 99)), 3),
            "send_late_max_ms": round(float(late_ms.max()), 3),
            "logging_samples_per_s": round(writer["samples_per_s"]) if writer else None}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=5.0, help="duration of each measurement [s]")
    parser.add_argument("--channels", type=int, default=8, help="accelerometers")
    parser.add_argument("--stream-seconds", type=float, default=20.0, help="the drive streamed meanwhile [s]")
    parser.add_argument("--dir", default=None, help="directory for the temporary session files")
    args = parser.parse_args()
    streaming_alone = measure_streaming(args.stream_seconds, args.channels, logging=False)
    streaming_logged = measure_streaming(args.stream_seconds, args.channels, logging=True, directory=args.dir)
    required = (args.channels + 1) * RATE
    full = measure_writer(args.seconds, args.channels, directory=args.dir)
    at_target = measure_writer(args.seconds, args.channels, rate=TARGET, directory=args.dir)
    realtime = measure_writer(args.seconds, args.channels, rate=required, block=10, directory=args.dir, probe=True)
    pacing_alone = measure_pacing_alone(min(args.seconds, 3.0))
    raw = measure_raw_h5py(min(args.seconds, 3.0), args.channels, directory=args.dir)
    flush_cost = [measure_flush_cost(args.seconds, args.channels, checksummed=checked, directory=args.dir)
                  for checked in (False, True, False, True)]  # interleaved: drift of a shared machine hits both
    rate = full["samples_per_s"]
    print(json.dumps({
        "figure": "session writer sustained logging rate",
        "value": round(rate),
        "unit": "samples/s (1 sample = one row of one stream: (t,ax,ay,az) of an accelerometer or "
                "(t,surge..yaw) of the commanded stream), appended and on disk including the run's end",
        "compared_with": {
            "required_realtime_samples_per_s": required,
            "required_is": f"{args.channels} accelerometers x 1 kHz + commanded stream x 1 kHz",
            "times_required": round(rate / required, 1),
            "target_samples_per_s": TARGET,
            "meets_target": rate >= TARGET,
            "plain_h5py_samples_per_s": round(raw["samples_per_s"]),
            "plain_h5py_is": "same rows appended with plain h5py, no SWMR/queue/thread, same run",
        },
        "data_at_risk_s": {
            "bound": 1.0,
            "definition": "largest time from append() to the end of the flush that put the sample on disk",
            "flush_interval_s": 0.25,
            "at_realtime_rate": round(realtime["max_append_to_disk_s"], 4),
            "at_target_rate": round(at_target["max_append_to_disk_s"], 4),
            "at_saturation": round(full["max_append_to_disk_s"], 4),
            "at_saturation_note": "unpaced producer keeps the queue full: latency = queued data / write speed",
        },
        "while_streaming": {
            "with_logging": streaming_logged,
            "without_logging": streaming_alone,
            "underruns_caused_by_logging": streaming_logged["underruns"] - streaming_alone["underruns"],
            "note": "1 kHz drive over MAVLink to the emulator (own process, loopback); the writer saturated by "
                    "the streaming process meanwhile, same run",
        },
        "checksum_cost_per_flush": {
            "without_checksums": [m for m in flush_cost if not m["checksummed"]],
            "with_checksums": [m for m in flush_cost if m["checksummed"]],
            "note": "one run's writer flushing every 0.25 s, rows paced at the 1,000,000 samples/s target; each "
                    "mode twice, interleaved, same run; checksum_ms_per_flush: CRC-32 of the blocks and the "
                    "checksum table's append",
        },
        "pacing_1khz_thread_late_ms": {
            "with_writer_at_realtime_rate": realtime["pacing_probe_late_ms"],
            "alone": pacing_alone,
            "note": "a sleep-paced 1 kHz thread in the same process (as the setpoint sender), same run",
        },
        "saturation": full,
        "paced_at_target": at_target,
        "paced_realtime": realtime,
        "python": sys.version.split()[0],
        "h5py": h5py.version.version,
        "hdf5": h5py.version.hdf5_version,
        "cpus": os.cpu_count(),
    }, indent=2))


if __name__ == "__main__":
    main()
