"""The crash-safe session log (`rig.session`): layout, never overwriting, live reading by another process,
and ``kill -9`` at random moments and at every step of a commit.

The writer processes of these tests are this file run as a script (``python tests/rig/test_session_log.py child
CONFIG``): a session at realistic rates (8 accelerometers × 1 kHz, 10 ms blocks, paced in real time) that
reports progress lines ``<run> <last sample index> <monotonic time>`` to a file after every block and
markers on stdout around create/resume/begin_run/end.
"""

from __future__ import annotations

import json
import math
import os
import random
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

import h5py
import numpy as np
import pytest

from rig.session import (
    SCHEMA,
    RunInfo,
    SessionError,
    SessionExistsError,
    SessionLog,
    list_sessions,
    open_session,
    read_session,
    writer_flags,
)
from rig.session.atomic import SessionFile
from tests.helpers.session_writer import (
    BATCH,
    BODIES,
    RATE,
    RIG_CONFIG,
    SEQUENCE,
    WriterChild,
    accel_values,
    commanded,
    final_resume_and_run,
    pose_values,
    prefix_rows,
    sensor_names,
    writer_config,
)

REPO = Path(__file__).resolve().parents[2]
MAX_LOSS = 1.0  # [s] the bound on lost samples


# ------------------------------------------------------------------------------------------------------
# Signals the writer processes record, and the checks of what they left
# ------------------------------------------------------------------------------------------------------



@dataclass
class _Seen:
    """What the checks remember of the session between kills."""

    rows: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)  # run → dataset → data
    losses: list[float] = field(default_factory=list)
    inside: dict[str, int] = field(default_factory=dict)


def _progress(path: Path) -> list[tuple[str, int, float]]:
    """Complete progress lines (run, last sample index, monotonic time) of a writer process."""
    if not path.exists():
        return []
    out = []
    for line in path.read_text().splitlines():
        parts = line.split()
        if len(parts) == 3:
            out.append((parts[0], int(parts[1]), float(parts[2])))
    return out


def _check_after_kill(path: Path, progress: Path, kill_time: float, ended: set[str], seen: _Seen,
                      n_sensors: int, speed: int = 1) -> dict:
    """The file a killed writer left: opens with plain h5py (SWMR read), holds an exact prefix of every stream
    that covers everything appended up to 1 s before the kill, keeps older runs unchanged, at most one run
    "running" (the last), and every run the writer finished "completed"."""
    with h5py.File(path, "r", swmr=True) as h5:  # what any reader does
        assert h5.attrs["schema"] == SCHEMA
        names = list(h5["runs"])
    session = read_session(path, timeout=2.0)
    assert [r["name"] for r in session["runs"]] == names
    present = {}
    for run in session["runs"]:
        present[run["name"]] = prefix_rows(run, n_sensors, speed)
        old = seen.rows.get(run["name"])
        if old is not None:  # a run of an earlier writer: its data never changes afterwards
            for key, data in old.items():
                now = run["accel"][key] if key.startswith("acc") else run[key]
                assert np.array_equal(now, data), f"run {run['name']} {key} changed after its writer died"
        seen.rows[run["name"]] = {**{s: run["accel"][s] for s in sensor_names(n_sensors)}, "pose": run["pose"]}
    statuses = [r["status"] for r in session["runs"]]
    running = [i for i, s in enumerate(statuses) if s == "running"]
    assert len(running) <= 1 and (not running or running[0] == len(statuses) - 1), statuses
    assert set(statuses) <= {"running", "completed", "interrupted"}, statuses
    for run in session["runs"]:
        # read_session verified every checksummed block (a flip would raise DamagedFileError); only the cut run
        # may hold rows after its last checksummed block
        assert run["checksums"]["state"] == "verified", run["checksums"]
        if run["status"] != "running" and run["name"] in ended:
            assert run["checksums"]["unverified"] == {}, (run["name"], run["checksums"])
        if run["name"] in ended:
            assert run["status"] == "completed", (run["name"], run["status"])
        if run["status"] != "running":
            datetime.fromisoformat(run["ended"])
        assert run["attempt"] == 1 + sum(r["plan_index"] == run["plan_index"] for r in session["runs"]
                                         if r["name"] < run["name"])
    # nothing appended more than MAX_LOSS before the kill is missing
    lines = _progress(progress)
    for name, k_last, wall in lines:
        if wall <= kill_time - MAX_LOSS:
            assert present.get(name, 0) >= k_last + 1, (
                f"run {name}: samples up to index {k_last} were appended {kill_time - wall:.2f} s before the kill "
                f"but the file holds {present.get(name, 0)}")
    missing = [wall for name, k_last, wall in lines if present.get(name, 0) < k_last + 1]
    if missing:
        seen.losses.append(kill_time - min(missing))
    return session



# ------------------------------------------------------------------------------------------------------
# Layout, attributes, API
# ------------------------------------------------------------------------------------------------------
def _begin(log: SessionLog, plan: int, sensors: list[str], **kw) -> object:
    return log.begin_run(plan, record=kw.pop("record", "RSN1063_NORTHR_RRS228"), scale_factor=0.68, angle_deg=5.0,
                         commanded=commanded(plan), bodies=BODIES, sensors=sensors, **kw)


def test_layout_and_attributes_follow_the_contract(tmp_path: Path) -> None:
    path = tmp_path / "session.h5"
    log = SessionLog.create(path, RIG_CONFIG, SEQUENCE, "0.1.0+test")
    assert log.sequence == SEQUENCE and log.rig_config == RIG_CONFIG and log.software_version == "0.1.0+test"
    run = _begin(log, 0, ["plate", "body1"], attrs={"governing_axis": "surge", "governing_quantity": "displacement",
                                                     "corner_hz": 0.1, "leg_check": True, "peaks": {"surge": 0.2}})
    ks = np.arange(250)
    run.append_accel("plate", ks / RATE, accel_values(0, ks))
    run.append_pose(ks / RATE, pose_values(ks))
    run.append_tilt(2, ks[::5] / RATE, 0.001 * ks[::5])
    run.append_following_error(ks[::20] / RATE, 1e-4 * np.outer(ks[::20], np.arange(1, 7)))
    run.add_detection(0.2, 1, +1, "sensor")
    run.add_detection(0.3, 2, -1, "operator")
    run.add_fault(0.1, "underrun", "setpoint buffer empty for 12 ms " + "é" * 400)  # cut at a character boundary
    run.add_event(0.0, "state: streaming")
    # while the run is recorded: status "running", ended "" (documented transient values), readable by SWMR
    time.sleep(0.6)
    live = read_session(path)
    assert live["runs"][0]["status"] == "running" and live["runs"][0]["ended"] == ""
    assert live["runs"][0]["accel"]["plate"].shape == (250, 4)  # flushed within the interval
    assert writer_flags(path) != 0
    info = run.end("completed", detections_expected=2)
    assert info == log.runs()[0] and info.status == "completed" and info.attempt == 1
    run2 = _begin(log, 1, ["plate", "body1"])
    run2.end("aborted", reason="operator abort")
    log.close()

    with h5py.File(path, "r") as h5:
        root = h5.attrs
        assert root["schema"] == "shaketable-rig/session/1" and root["software_version"] == "0.1.0+test"
        datetime.fromisoformat(root["created"])
        assert json.loads(root["rig_config"]) == RIG_CONFIG and json.loads(root["sequence"]) == SEQUENCE
        assert list(h5["runs"]) == ["0001", "0002"]
        g = h5["runs/0001"]
        assert g.attrs["record"] == "RSN1063_NORTHR_RRS228"
        assert g.attrs["scale_factor"] == 0.68 and g.attrs["angle_deg"] == 5.0
        assert g.attrs["status"] == "completed" and isinstance(g.attrs["status"], str)
        assert datetime.fromisoformat(g.attrs["ended"]) >= datetime.fromisoformat(g.attrs["started"])
        assert g.attrs["plan_index"] == 0 and g.attrs["attempt"] == 1
        assert g.attrs["governing_axis"] == "surge" and g.attrs["leg_check"] and g.attrs["detections_expected"] == 2
        assert json.loads(g.attrs["peaks"]) == {"surge": 0.2}
        assert g["commanded"].dtype == np.float64 and np.array_equal(g["commanded"][()], commanded(0))
        assert set(g["accel"]) == {"plate", "body1"}
        assert g["accel/plate"].dtype == np.float64 and g["accel/plate"].shape == (250, 4)
        assert g["accel/body1"].shape == (0, 4)
        assert g["accel/plate"].attrs["columns"] == "t,ax,ay,az"
        assert g["pose"].shape == (250, 7) and g["pose"].attrs["columns"].startswith("t,surge,sway,heave")
        assert set(g["tilt"]) == {"1", "2"} and g["tilt/1"].shape == (0, 2)  # one per body
        assert g["tilt/2"].shape == (50, 2) and g["tilt/2"].attrs["columns"] == "t,angle"
        assert g["tilt/2"].attrs["units"] == "s,rad"
        errors = g["following_error"]  # each leg's, as the statuses carry it
        assert errors.shape == (13, 7) and errors.attrs["columns"] == "t,leg1,leg2,leg3,leg4,leg5,leg6"
        assert errors.attrs["units"] == "s,m,m,m,m,m,m" and errors[1, 6] == pytest.approx(20 * 6e-4)
        det = g["detections"][()]
        assert det.dtype.names == ("t", "body_id", "direction", "source")
        assert det["body_id"].tolist() == [1, 2] and det["direction"].tolist() == [1, -1]
        assert [s.decode() for s in det["source"]] == ["sensor", "operator"]
        bodies = g["bodies"][()]
        assert bodies.dtype.names[:7] == ("body_id", "b", "h", "depth", "mass", "x", "y")
        assert bodies["b"].tolist() == [0.10, 0.05] and bodies["name"][0] == b"B1"
        assert g["faults"].dtype.names == ("t", "name", "detail") and g["events"].dtype.names == ("t", "text")
        for name in ("accel/plate", "pose", "detections", "faults", "events", "commanded"):
            assert g[name].chunks is not None and g[name].maxshape[0] is None
        assert h5["runs/0002"].attrs["status"] == "aborted" and h5["runs/0002"].attrs["reason"] == "operator abort"

    s = read_session(path)
    assert s["rig_config"] == RIG_CONFIG and s["sequence"] == SEQUENCE and s["software_version"] == "0.1.0+test"
    r = s["runs"][0]
    assert r["sensors"] == ["plate", "body1"] and r["status"] == "completed"
    assert r["detections"] == [{"t": 0.2, "body_id": 1, "direction": 1, "source": "sensor"},
                               {"t": 0.3, "body_id": 2, "direction": -1, "source": "operator"}]
    assert r["bodies"][0] == BODIES[0]  # with its centre of gravity
    no_cg = {key: value for key, value in r["bodies"][1].items() if key not in ("b_cg", "h_cg")}
    assert no_cg == {**BODIES[1], "name": ""} and math.isnan(r["bodies"][1]["b_cg"]) and math.isnan(
        r["bodies"][1]["h_cg"])  # not given: NaN, the middle
    assert r["faults"][0]["name"] == "underrun" and r["faults"][0]["detail"].endswith("é")
    assert len(r["faults"][0]["detail"].encode()) <= 512
    assert r["events"] == [{"t": 0.0, "text": "state: streaming"}]
    assert set(r["tilt"]) == {1, 2} and r["tilt"][1].shape == (0, 2)
    assert np.array_equal(r["tilt"][2], np.column_stack([ks[::5] / RATE, 0.001 * ks[::5]]))

    # `rig analyze` later adds groups with plain h5py; the session can still be read and resumed afterwards
    with h5py.File(path, "a") as h5:
        grp = h5["runs/0001"].create_group("analysis")
        grp.attrs["model"] = "rocking"
        grp.create_dataset("predicted_direction", data=np.array([1, -1], dtype=np.int8))
    assert read_session(path)["runs"][0]["analysis"]["predicted_direction"].tolist() == [1, -1]
    log = SessionLog.resume(path)
    assert log.sequence == SEQUENCE and log.rig_config == RIG_CONFIG and log.created == s["created"]
    _begin(log, 2, ["plate"]).end("completed")
    log.close()
    assert [r["status"] for r in read_session(path)["runs"]] == ["completed", "aborted", "completed"]


def test_refuses_an_existing_file_and_leaves_it_untouched(tmp_path: Path) -> None:
    other = tmp_path / "other.h5"
    other.write_bytes(os.urandom(5000))
    session = tmp_path / "session.h5"
    SessionLog.create(session, RIG_CONFIG, SEQUENCE, "1").close()
    for path in (other, session):
        before, stat = path.read_bytes(), path.stat()
        with pytest.raises(SessionExistsError, match=path.name) as err:
            SessionLog.create(path, {"x": 1}, {}, "2")
        assert isinstance(err.value, SessionError) and isinstance(err.value, FileExistsError)
        assert path.read_bytes() == before and path.stat().st_mtime_ns == stat.st_mtime_ns
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.h5", "session.h5"]  # no temporaries left


@pytest.mark.integration
def test_one_writer_at_a_time_and_resume_of_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "s.h5"
    log = SessionLog.create(path, {}, {}, "1")
    with pytest.raises(SessionError, match="another process"):
        SessionLog.resume(path)
    if os.environ.get("HDF5_USE_FILE_LOCKING", "").upper() not in ("FALSE", "0"):
        probe = subprocess.run([sys.executable, "-c", f"import h5py; h5py.File({str(path)!r}, 'a')"],
                               capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(REPO)})
        assert probe.returncode != 0 and "lock" in probe.stderr  # an HDF5 writer with default locking is kept out
    log.close()
    SessionLog.resume(path).close()
    with pytest.raises(SessionError, match="no such session file"):
        SessionLog.resume(tmp_path / "missing.h5")


def test_resume_leaves_files_that_are_not_sessions_alone(tmp_path: Path) -> None:
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w", libver="latest") as h5:
        h5.attrs["schema"] = "someone/else/1"
    junk = tmp_path / "junk.h5"
    junk.write_bytes(os.urandom(300))
    for path, message in ((foreign, "schema attribute"), (junk, "no HDF5 signature")):
        before = path.read_bytes()
        with pytest.raises(SessionError, match=message):
            SessionLog.resume(path)
        assert path.read_bytes() == before
    with pytest.raises(SessionError, match="flush_interval"):
        SessionLog.create(tmp_path / "slow.h5", {}, {}, "1", flush_interval=2.0)
    assert not (tmp_path / "slow.h5").exists()


def test_api_validation(tmp_path: Path) -> None:
    log = SessionLog.create(tmp_path / "s.h5", {}, {}, "1")
    with pytest.raises(SessionError, match=r"\(N, 7\)"):
        log.begin_run(0, record="r", scale_factor=1, angle_deg=0, commanded=np.zeros((5, 6)), bodies=[], sensors=[])
    with pytest.raises(SessionError, match="reserved"):
        _begin(log, 0, ["a"], attrs={"status": "x"})
    run = _begin(log, 0, ["a"])
    with pytest.raises(SessionError, match="still being recorded"):
        _begin(log, 1, ["a"])
    with pytest.raises(SessionError, match="unknown sensor"):
        run.append_accel("b", np.zeros(2), np.zeros((2, 3)))
    with pytest.raises(SessionError, match=r"\(k, 3\)"):
        run.append_accel("a", np.zeros(2), np.zeros((3, 3)))
    with pytest.raises(SessionError, match="body 7 is not on the plate"):
        run.append_tilt(7, np.zeros(2), np.zeros(2))
    with pytest.raises(SessionError, match=r"tilt of body 1.*\(k, 1\)"):
        run.append_tilt(1, np.zeros(2), np.zeros(3))
    with pytest.raises(SessionError, match="source"):
        run.add_detection(0.0, 1, 1, "camera")
    with pytest.raises(SessionError, match="status"):
        run.end("done")
    run.end("refused")
    with pytest.raises(SessionError, match="has ended"):
        run.append_pose(np.zeros(1), np.zeros((1, 6)))
    # a run refused before its drive was prepared: no scale factor, no commanded motion; None attributes left out
    refused = log.begin_run(1, record="r", scale_factor=float("nan"), angle_deg=4.0, commanded=np.zeros((0, 7)),
                            bodies=[], sensors=["a"], attrs={"reason": "exceeds the table", "table_url": None})
    info = refused.end("refused", reason="exceeds the table's stroke")
    assert math.isnan(info.scale_factor) and info.status == "refused"
    log.close()
    run = read_session(tmp_path / "s.h5")["runs"][1]
    assert math.isnan(run["scale_factor"]) and run["attrs"]["reason"] == "exceeds the table's stroke"
    assert "table_url" not in run["attrs"]


def test_in_process_reader_handle_blocks_begin_run_with_a_clear_error(tmp_path: Path) -> None:
    path = tmp_path / "s.h5"
    log = SessionLog.create(path, {}, {}, "1")
    with open_session(path), pytest.raises(SessionError, match="close such handles"):  # handle in this process
        _begin(log, 0, ["acc0"])
    assert log.runs()[0].status == "interrupted" and log.active_run is None  # not left "running"
    run = _begin(log, 0, ["acc0"])
    assert run.attempt == 2
    assert read_session(path)["runs"][1]["status"] == "running"  # read_session in-process during the run is fine
    run.end("completed")
    log.close()


def test_done_plan_indices_and_attempts(tmp_path: Path) -> None:
    path = tmp_path / "s.h5"
    log = SessionLog.create(path, {}, {}, "1")
    for plan, status in [(0, "completed"), (1, "aborted"), (2, "refused"), (3, "skipped"), (1, "completed"),
                         (4, "interrupted")]:
        _begin(log, plan, ["a"]).end(status)
    assert log.done_plan_indices() == {0, 1, 2, 3}
    assert [(r.name, r.plan_index, r.attempt) for r in log.runs()] == [
        ("0001", 0, 1), ("0002", 1, 1), ("0003", 2, 1), ("0004", 3, 1), ("0005", 1, 2), ("0006", 4, 1)]
    _begin(log, 4, ["a"])  # still running when the log is closed: ends interrupted
    log.close()
    log = SessionLog.resume(path)
    assert log.runs()[-1] == RunInfo(**{**log.runs()[-1].__dict__, "status": "interrupted", "attempt": 2})
    assert 4 not in log.done_plan_indices()
    log.close()


@pytest.mark.integration
def test_a_second_process_reads_the_growing_run(tmp_path: Path) -> None:
    path = tmp_path / "live.h5"
    log = SessionLog.create(path, RIG_CONFIG, SEQUENCE, "1")
    run = _begin(log, 0, sensor_names(8))
    reader = subprocess.Popen([sys.executable, "-m", "tests.helpers.session_writer", "reader", str(path), "2.0"],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              env={**os.environ, "PYTHONPATH": str(REPO)}, cwd=REPO)
    appended = [(time.monotonic(), 0)]  # (time, rows appended by then); CLOCK_MONOTONIC is shared by processes
    t0 = time.monotonic()
    k = 0
    while reader.poll() is None and time.monotonic() - t0 < 20:
        time.sleep(max(0.0, t0 + (k + BATCH) / RATE - time.monotonic()))
        ks = np.arange(k, k + BATCH)
        for i, sensor in enumerate(sensor_names(8)):
            run.append_accel(sensor, ks / RATE, accel_values(i, ks))
        run.append_pose(ks / RATE, pose_values(ks))
        k += BATCH
        appended.append((time.monotonic(), k))
    out, err = reader.communicate(timeout=30)
    run.end("completed")
    log.close()
    assert reader.returncode == 0, err
    report = json.loads(out)
    assert report["plain_open"] == "refused"  # without swmr=True HDF5 refuses a file being written
    sizes = [n for _, n in report["sizes"]]
    assert sizes == sorted(sizes) and len(set(sizes)) >= 4, sizes  # it saw the dataset grow, never shrink
    times = np.array([t for t, _ in appended])
    counts = np.array([n for _, n in appended])
    for seen_at, n in report["sizes"]:
        assert n <= counts[np.searchsorted(times, seen_at, "right") - 1]  # nothing the writer had not appended
        behind = counts[max(np.searchsorted(times, seen_at - MAX_LOSS, "right") - 1, 0)]
        assert n >= behind, f"at {seen_at:.2f} the reader saw {n} rows, {behind} were appended > 1 s before"
    assert report["prefix_ok"], "the reader saw samples that differ from what was appended"


def test_list_sessions(tmp_path: Path) -> None:
    for name, statuses in (("a.h5", ["completed", "aborted"]), ("b.h5", ["completed"])):
        log = SessionLog.create(tmp_path / name, {}, {}, "1")
        for plan, status in enumerate(statuses):
            _begin(log, plan, ["a"]).end(status)
        log.close()
    with h5py.File(tmp_path / "c.h5", "w") as h5:
        h5.attrs["schema"] = "something else"
    (tmp_path / "notes.txt").write_text("x")
    (tmp_path / ".b.h5.0123.shadow").write_bytes(b"junk")
    found = list_sessions(tmp_path)
    assert [Path(s["path"]).name for s in found] == ["a.h5", "b.h5"]
    assert found[0]["runs"] == 2 and found[0]["statuses"] == {"completed": 1, "aborted": 1}
    assert not found[0]["open_for_write"]


# ------------------------------------------------------------------------------------------------------
# Atomic commits
# ------------------------------------------------------------------------------------------------------
def test_structural_changes_stay_on_the_one_page_path(tmp_path: Path) -> None:
    """Begin and end of 130 runs (beyond the runs that fit /runs's first header chunk) never need the slow copy."""
    path = tmp_path / "many.h5"
    log = SessionLog.create(path, {}, {}, "1", flush_interval=0.01)
    methods = []
    for plan in range(130):
        run = log.begin_run(plan, record="r", scale_factor=1.0, angle_deg=0.0, commanded=np.zeros((10, 7)),
                            bodies=BODIES[:1], sensors=sensor_names(8), attrs={"governing_axis": "sway"})
        methods.append(("begin", log.last_commit.method, log.last_commit.pages))
        run.end("completed", peak=0.1)
        methods.append(("end", log.last_commit.method, log.last_commit.pages))
    log.close()
    assert {m for _, m, _ in methods} == {"pages"}, sorted(set(methods))
    assert max(p for _, _, p in methods) <= 2
    assert len(read_session(path, data=False)["runs"]) == 130


def test_a_change_of_two_pages_takes_the_shadow_copy_and_stays_correct(tmp_path: Path) -> None:
    path = tmp_path / "s.h5"
    log = SessionLog.create(path, {}, {}, "1")
    for plan in range(2):
        run = _begin(log, plan, ["acc0"], attrs={"note": "before"})
        run.append_accel("acc0", np.arange(5) / RATE, accel_values(0, np.arange(5)))
        run.end("completed", note="after")
        assert log.last_commit.method == "pages"
    log.close()
    file = SessionFile(path, os.open(path, os.O_RDWR))
    with file.transaction() as h5:  # two run headers in two pages: not one page write any more
        for name in ("0001", "0002"):
            h5["runs"][name].attrs["checked"] = True
    assert file.last_commit.method == "shadow"
    file.close()
    log = SessionLog.resume(path)  # the log goes on with the new file
    _begin(log, 2, ["acc0"]).end("completed")
    log.close()
    s = read_session(path)
    assert [r["attrs"].get("checked") for r in s["runs"]] == [True, True, None]
    prefix_rows(s["runs"][0], 1)
    assert len(s["runs"][0]["accel"]["acc0"]) == 5 and s["runs"][0]["attrs"]["note"] == "after"
    assert not list(tmp_path.glob(".*"))


def test_a_failed_transaction_leaves_the_file_as_it_was(tmp_path: Path) -> None:
    path = tmp_path / "s.h5"
    SessionLog.create(path, {}, {}, "1").close()
    before = path.read_bytes()
    file = SessionFile(path, os.open(path, os.O_RDWR))
    with pytest.raises(RuntimeError), file.transaction() as h5:
        h5["runs"].create_group("0001").attrs["x"] = 1
        raise RuntimeError("boom")
    file.close()
    assert path.read_bytes()[: len(before)] == before  # at most junk after the end of allocation
    assert read_session(path)["runs"] == []


# ------------------------------------------------------------------------------------------------------
# kill -9
# ------------------------------------------------------------------------------------------------------
def _kill_campaign(tmp_path: Path, points: int, seed: int, *, speed: int = 1,
                   modes: tuple[str, ...] = ("time", "B", "E", "R", "F", "F")) -> _Seen:
    """One session, written by a chain of writer processes, each resuming it and killed: at a random time
    (``time``), or a random 0–8 ms after it announced resume (``R``), begin_run (``B``), end (``E``), or 0–3 ms
    after its writer thread started a flush (``F``, after a random 0.2–1.5 s)."""
    rng = random.Random(seed)
    path = tmp_path / "killed.h5"
    seen = _Seen()
    for i in range(points):
        progress = tmp_path / f"progress{i}.txt"
        child = WriterChild(writer_config(path, progress, seed * 1000 + i, speed=speed,
                               run_seconds=(0.3 * speed, 1.0 * speed)))
        mode = rng.choice(modes)
        if mode == "time":
            time.sleep(rng.uniform(0.05, 2.0))
        elif mode == "F":
            time.sleep(rng.uniform(0.2, 1.5))
            if not child.wait_count("F", child.count("F") + 1, timeout=10):
                pytest.fail(f"writer never flushed: {child.stderr()}")
            time.sleep(rng.uniform(0.0, 0.003))
        else:
            mode = "C" if mode == "R" and not path.exists() else mode
            if not child.wait_marker(mode, timeout=10):
                pytest.fail(f"writer never reached {mode!r}: {child.stderr()}")
            time.sleep(rng.uniform(0.0, 0.008))
        kill_time = child.kill()
        if mode != "time":  # did the kill land inside the operation (its completion marker not yet out)?
            done = mode.lower()
            if child.count(done) < child.count(mode):
                seen.inside[mode] = seen.inside.get(mode, 0) + 1
        assert path.exists()
        _check_after_kill(path, progress, kill_time, child.ended(), seen, 8, speed)
    return seen


@pytest.mark.integration
def test_kill_minus_9_at_random_moments(tmp_path: Path) -> None:
    seen = _kill_campaign(tmp_path, points=22, seed=20260509)
    print(f"\nkills inside operations: {seen.inside}; data lost per kill [s]: "
          f"{[round(x, 3) for x in seen.losses]}")
    assert seen.losses and max(seen.losses) <= MAX_LOSS
    assert sum(seen.inside.values()) >= 3  # some kills landed inside resume/begin_run/end/a flush
    final_resume_and_run(tmp_path / "killed.h5", 8)


@pytest.mark.integration
@pytest.mark.slow
def test_kill_minus_9_at_random_moments_exhaustive(tmp_path: Path) -> None:
    seen = _kill_campaign(tmp_path, points=120, seed=7)
    print(f"\nkills inside operations: {seen.inside}; worst loss {max(seen.losses):.3f} s")
    assert sum(seen.inside.values()) >= 10
    final_resume_and_run(tmp_path / "killed.h5", 8)


@pytest.mark.integration
@pytest.mark.slow
def test_kill_minus_9_during_large_flushes(tmp_path: Path) -> None:
    """Samples appended 50× faster than real time (450,000 rows/s, ~3.6 MB per flush)."""
    seen = _kill_campaign(tmp_path, points=40, seed=11, speed=50, modes=("time", "F"))
    print(f"\nkills inside operations: {seen.inside}; worst loss {max(seen.losses):.3f} s over "
          f"{len(seen.losses)} kills with samples in flight")
    final_resume_and_run(tmp_path / "killed.h5", 8)


#: (crash point[:pass], what the session must look like afterwards) in chain order; each writer resumes the
#: session the previous one left. ``cut`` = status of the run the previous writer left unfinished.
FAILPOINTS = [
    ("writer:flushed:3", None),  # mid-run, SWMR flags left set
    ("resume:flags-cleared", "running"),  # flags cleared, the cut run not yet marked
    ("commit:closed", "running"),  # resume's transaction built, nothing committed
    ("commit:new-space", "running"),  # new space written, nothing linked
    ("commit:page:1", "running"),  # superblock EOA written (alone harmless), header page not yet
    ("commit:page:2", "interrupted"),  # header page written: the run is interrupted
    ("begin:committed", None),  # run group created, recording not started
    ("writer:flushed:2", None),
    ("end:swmr-closed", None),  # samples complete and closed, final attributes not set
    # with every commit forced onto the copy-and-rename path:
    ("shadow:before-rename", "running"),  # resume's copy of the file is complete but not yet in place
    ("shadow:renamed", "interrupted"),  # resume's copy is in place
    ("shadow:renamed:2", None),  # (nothing to resume) begin's copy in place, then end's copy in place
    ("shadow:before-rename:2", None),  # end's copy complete, not in place
]


@pytest.mark.integration
def test_kill_at_every_step_of_a_commit(tmp_path: Path) -> None:
    path = tmp_path / "steps.h5"
    seen = _Seen()
    prev_cut = None
    for i, (point, expect_cut) in enumerate(FAILPOINTS):
        progress = tmp_path / f"progress{i}.txt"
        config = writer_config(path, progress, i, sensors=8, run_seconds=(0.4, 0.6))
        env = {"RIG_SESSION_FAILPOINT": point, "RIG_SESSION_FORCE_SHADOW": "1" if point.startswith("shadow") else "0"}
        child = WriterChild(config, env=env)
        try:
            child.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            child.kill()
            pytest.fail(f"{point}: the writer did not reach its crash point")
        died = child.wait(5)
        assert child.proc.returncode == -signal.SIGKILL, (point, child.stderr())
        session = _check_after_kill(path, progress, died, child.ended(), seen, 8)
        if expect_cut is not None:
            cut = next(r for r in session["runs"] if r["name"] == prev_cut)
            assert cut["status"] == expect_cut, (point, cut["status"])
        last = session["runs"][-1]
        if point in ("begin:committed", "end:swmr-closed", "shadow:before-rename:2"):
            assert last["status"] == "running", point
        if point in ("end:swmr-closed", "shadow:before-rename:2"):
            assert prefix_rows(last, 8) >= 0.4 * RATE  # everything flushed at the end is there
        if point == "shadow:renamed:2":
            assert last["status"] == "completed" and last["attrs"]["note"] == "after"
        if point.startswith("shadow:renamed"):
            assert not list(tmp_path.glob(".steps.h5.*"))  # resume removed the leftover of the killed copy
        running = [r["name"] for r in session["runs"] if r["status"] == "running"]
        prev_cut = running[-1] if running else prev_cut
    final_resume_and_run(path, 8)


# ------------------------------------------------------------------------------------------------------
# The processes these tests start
# ------------------------------------------------------------------------------------------------------
