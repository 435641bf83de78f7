"""The session-file writer and reader processes of the ``kill -9`` campaigns (tests/rig/test_session_log.py,
test_session_recover.py, test_session_space.py): ``python -m tests.helpers.session_writer child CONFIG`` writes a
session at realistic rates (8 accelerometers × 1 kHz, 10 ms blocks, paced in real time) and prints a marker at each
step; ``… reader PATH SECONDS`` reads the growing file with SWMR and prints a JSON report."""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import h5py
import numpy as np

from rig.session import SessionLog, read_session, writer_flags
from rig.session.writer import BlockWriter

REPO = Path(__file__).resolve().parents[2]
RATE = 1000.0  # [Hz] accelerometer and pose rate of the writer processes


BATCH = 10  # samples per block (10 ms)


RIG_CONFIG = {"table": {"transport": "emulator", "rate_hz": 1000}, "accelerometers": 8}


SEQUENCE = {"angles_deg": [0, 4], "records": ["suite:a", "suite:b"], "repetitions": 1}


def accel_values(sensor: int, ks: np.ndarray) -> np.ndarray:
    """Deterministic, exactly representable samples of sensor ``sensor`` at indices ``ks`` [m/s²]."""
    base = sensor * 1e6 + ks.astype(np.float64)
    return np.column_stack([base, -base, ks * 0.5])


def pose_values(ks: np.ndarray) -> np.ndarray:
    k = ks.astype(np.float64)
    return np.column_stack([k, k * 2, k * 3, -k, -k * 2, -k * 3]) * 1e-6


def commanded(plan: int) -> np.ndarray:
    t = np.arange(500) / 100.0
    return np.column_stack([t, *(np.sin(t + i + plan) * 0.01 for i in range(6))])


BODIES = [{"body_id": 1, "b": 0.10, "h": 0.50, "depth": 0.10, "mass": 4.0, "x": 0.20, "y": -0.1, "name": "B1",
           "b_cg": 0.052, "h_cg": 0.24},
          {"body_id": 2, "b": 0.05, "h": 0.30, "depth": 0.05, "mass": 1.0, "x": -0.2, "y": 0.1}]


def sensor_names(n: int) -> list[str]:
    return [f"acc{i}" for i in range(n)]


def prefix_rows(run: dict, n_sensors: int, speed: int = 1) -> int:
    """Check every growing dataset of a run is an exact prefix of what the writer appended; the common row count."""
    counts = []
    for i, sensor in enumerate(sensor_names(n_sensors)):
        a = run["accel"][sensor]
        ks = np.arange(len(a))
        assert a.shape[1] == 4
        assert np.array_equal(a[:, 0], ks / RATE), f"run {run['name']} {sensor}: time column is not the prefix"
        assert np.array_equal(a[:, 1:], accel_values(i, ks)), f"run {run['name']} {sensor}: wrong samples"
        counts.append(len(a))
    pose = run["pose"]
    ks = np.arange(len(pose))
    assert np.array_equal(pose[:, 0], ks / RATE) and np.array_equal(pose[:, 1:], pose_values(ks))
    counts.append(len(pose))
    # all streams get the same blocks, but each dataset is written separately: a kill between two dataset writes
    # of one flush may leave them one flush (0.25 s) apart
    assert max(counts) - min(counts) <= RATE * speed, counts
    return min(counts)


class WriterChild:
    """A writer process (``python -m tests.helpers.session_writer child CONFIG``) and its stdout markers."""

    def __init__(self, config: dict, env: dict | None = None) -> None:
        full_env = {key: value for key, value in os.environ.items() if key != "RIG_SESSION_FAILPOINT"}
        full_env.update({"PYTHONPATH": str(REPO), **(env or {})})
        command = [sys.executable, "-m", "tests.helpers.session_writer", "child", json.dumps(config)]
        self.proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=full_env,
                                     cwd=REPO)
        self.markers: list[tuple[str, float]] = []
        self._cond = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            with self._cond:
                self.markers.append((line.strip(), time.monotonic()))
                self._cond.notify_all()

    def wait_marker(self, prefix: str, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                if any(m.startswith(prefix) for m, _ in self.markers):
                    return True
                left = deadline - time.monotonic()
                if left <= 0 or self.proc.poll() is not None:
                    return False
                self._cond.wait(left)

    def count(self, prefix: str) -> int:
        with self._cond:
            return sum(m.startswith(prefix) for m, _ in self.markers)

    def wait_count(self, prefix: str, n: int, timeout: float) -> bool:
        """Wait until ``n`` markers starting with ``prefix`` have come."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while sum(m.startswith(prefix) for m, _ in self.markers) < n:
                left = deadline - time.monotonic()
                if left <= 0 or self.proc.poll() is not None:
                    return False
                self._cond.wait(left)
            return True

    def kill(self) -> float:
        t = time.monotonic()
        if self.proc.poll() is None:
            os.kill(self.proc.pid, signal.SIGKILL)
        self.proc.wait(timeout=30)
        self._reader.join(timeout=5)
        return t

    def wait(self, timeout: float) -> float:
        self.proc.wait(timeout=timeout)
        t = time.monotonic()
        self._reader.join(timeout=5)
        return t

    def ended(self) -> set[str]:
        return {m[1:].split()[0] for m, _ in self.markers if m.startswith("e")}

    def stderr(self) -> str:
        assert self.proc.stderr is not None
        return self.proc.stderr.read()


def writer_config(path: Path, progress: Path, seed: int, *, sensors: int = 8,
            run_seconds: tuple[float, float] = (0.3, 1.0), speed: int = 1) -> dict:
    """``run_seconds``: range of run lengths on the run clock; ``speed``: samples appended ``speed`` times faster
    than real time (in ``speed``-times larger blocks), for flushes big enough that kills land inside them."""
    return {"path": str(path), "progress": str(progress), "seed": seed, "sensors": sensors, "plan": 10_000,
            "run_seconds": list(run_seconds), "speed": speed}


def final_resume_and_run(path: Path, n_sensors: int) -> None:
    """After all the kills: resume marks the cut run interrupted, and new runs work."""
    log = SessionLog.resume(path)
    try:
        before = log.runs()
        assert all(r.status != "running" for r in before)
        done = log.done_plan_indices()
        assert done == {r.plan_index for r in before if r.status == "completed"}
        redo = [r.plan_index for r in before if r.status == "interrupted" and r.plan_index not in done]
        plan = redo[0] if redo else 99_999
        run = log.begin_run(plan, record="final", scale_factor=1.0, angle_deg=0.0, commanded=commanded(0),
                            bodies=BODIES, sensors=sensor_names(n_sensors))
        ks = np.arange(100)
        for i, sensor in enumerate(sensor_names(n_sensors)):
            run.append_accel(sensor, ks / RATE, accel_values(i, ks))
        run.append_pose(ks / RATE, pose_values(ks))
        info = run.end("completed")
        assert info.attempt == 1 + sum(r.plan_index == plan for r in before)
    finally:
        log.close()
    session = read_session(path)
    assert session["runs"][-1]["status"] == "completed" and prefix_rows(session["runs"][-1], n_sensors) == 100
    assert writer_flags(path) == 0
    with h5py.File(path, "r") as h5:  # after a clean close also a non-SWMR reader opens it
        assert len(h5["runs"]) == len(before) + 1


def child_main(config: dict) -> None:
    """Writer: create or resume the session, then run plan entries not yet done, in real time, forever."""
    rng = random.Random(config["seed"])
    path = Path(config["path"])
    sensors = sensor_names(config["sensors"])
    progress = os.open(config["progress"], os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)

    lock = threading.Lock()

    def mark(text: str) -> None:
        with lock:
            sys.stdout.write(text + "\n")
            sys.stdout.flush()

    original_flush = BlockWriter._flush_once

    def traced_flush(self: BlockWriter) -> None:  # "F" when a flush with data starts, "f" when it is done
        busy = bool(self._queue)
        if busy:
            mark("F")
        original_flush(self)
        if busy:
            mark("f")

    BlockWriter._flush_once = traced_flush  # type: ignore[method-assign]

    if path.exists():
        mark("R")
        log = SessionLog.resume(path)
        mark("r")
    else:
        mark("C")
        log = SessionLog.create(path, RIG_CONFIG, SEQUENCE, "0.1.0+killtest")
        mark("c")
    while True:
        done = log.done_plan_indices()
        plan = next(i for i in range(config["plan"]) if i not in done)
        mark(f"B{plan}")
        attrs = {"note": "before", "governing_axis": "surge"}
        run = log.begin_run(plan, record=f"REC{plan}", scale_factor=0.5, angle_deg=4.0, commanded=commanded(plan),
                            bodies=BODIES, sensors=sensors, attrs=attrs)
        mark(f"b{run.name}")
        n_total = int(rng.uniform(*config["run_seconds"]) * RATE)
        speed = config["speed"]
        t0 = time.monotonic()
        k = 0
        while k < n_total:
            time.sleep(max(0.0, t0 + (k + BATCH * speed) / (RATE * speed) - time.monotonic()))
            ks = np.arange(k, min(k + BATCH * speed, n_total))
            for i, sensor in enumerate(sensors):
                run.append_accel(sensor, ks / RATE, accel_values(i, ks))
            run.append_pose(ks / RATE, pose_values(ks))
            if k % (200 * speed) == 0:
                run.add_event(ks[0] / RATE, f"block {k}")
            os.write(progress, f"{run.name} {ks[-1]} {time.monotonic():.6f}\n".encode())
            k = int(ks[-1]) + 1
        run.add_detection(k / RATE, 1, 1, "sensor")
        mark(f"E{run.name}")
        run.end("completed", note="after")
        mark(f"e{run.name}")


def reader_main(path: str, seconds: float) -> None:
    """Reader: refused without SWMR; with ``swmr=True`` polls the growing dataset; prints a JSON report."""
    report: dict = {"sizes": [], "prefix_ok": True}
    try:
        with h5py.File(path, "r"):
            report["plain_open"] = "opened"
    except OSError:
        report["plain_open"] = "refused"
    t0 = time.monotonic()
    with h5py.File(path, "r", swmr=True) as h5:
        ds = h5["runs/0001/accel/acc3"]
        while time.monotonic() - t0 < seconds:
            ds.refresh()
            n = ds.shape[0]
            report["sizes"].append((time.monotonic(), n))
            if n:
                data = ds[:n]
                ks = np.arange(n)
                report["prefix_ok"] &= bool(np.array_equal(data[:, 0], ks / RATE)
                                            and np.array_equal(data[:, 1:], accel_values(3, ks)))
            time.sleep(0.1)
    read_session(path)  # and the reader's helper works meanwhile
    print(json.dumps(report))


if __name__ == "__main__":
    if sys.argv[1] == "child":
        child_main(json.loads(sys.argv[2]))
    elif sys.argv[1] == "reader":
        reader_main(sys.argv[2], float(sys.argv[3]))
