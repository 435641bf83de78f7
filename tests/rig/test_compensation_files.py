"""The compensated drive file (rig.drive.file) and a sequence that plays it (``drive = "FILE"``); the
session's /compensation group (rig.compensation.store) read back."""

from __future__ import annotations

import math

import h5py
import numpy as np
import pytest

from analysis.table.model import TableModel
from rig.compensation import store
from rig.compensation.identify import frequency_response, identification_drive
from rig.compensation.iteration import compensate
from rig.compensation.laws import DiagonalLaw, MimoLaw
from rig.compensation.mimo import estimate
from rig.compensation.signals import base_accelerations
from rig.compensation.store import response_from_rows, response_rows
from rig.drive import prepare_drive
from rig.drive.file import DriveFileError, load_drive, save_drive
from rig.report.compensation_report import compensation_section
from rig.sequence import SequenceError, load_sequence
from rig.sequence.model import RecordEntry
from rig.sequence.records import load_entry
from rig.session import SessionLog
from sim_table.offline import play_offline

TABLE = TableModel()
BETA = math.radians(4.0)


@pytest.fixture(scope="module")
def compensated():
    ident = identification_drive(TABLE, BETA, duration=20.0)
    frf = frequency_response(ident.accelerations[:, :3], base_accelerations(play_offline(TABLE, ident.poses), BETA),
                             TABLE.controller_rate)
    motion = load_entry(RecordEntry(spec="fema:KOBE/NIS000", resolved="fema:KOBE/NIS000", window=(5.0, 10.0)))
    drive = prepare_drive(motion, angle=BETA, table=TABLE, corner=1.0, settle=0.5, ramps=False, headroom=0.1)
    result = compensate(drive, DiagonalLaw(frf), lambda d, k: play_offline(TABLE, d.poses, seed=k), iterations=2)
    return drive, result, frf


def test_drive_file_round_trip_and_never_overwritten(tmp_path, compensated):
    _, result, _ = compensated
    path = save_drive(tmp_path / "nis.drive.h5", result.drive, result.to_json())
    back = load_drive(path, TABLE, angle=BETA)
    for name in ("t", "poses", "velocities", "accelerations"):
        assert np.array_equal(getattr(back, name), getattr(result.drive, name))
    assert back.record == result.drive.record and back.motion == pytest.approx(result.drive.motion)
    with pytest.raises(DriveFileError, match="already exists"):
        save_drive(path, result.drive, {})
    with pytest.raises(DriveFileError, match="iterated at β = 4°, not 5°"):
        load_drive(path, TABLE, angle=math.radians(5.0))
    (tmp_path / "other.h5").write_bytes(b"not hdf5")
    with pytest.raises(DriveFileError, match=r"other\.h5: unreadable"):
        load_drive(tmp_path / "other.h5")


def test_a_sequence_plays_the_compensated_drive(tmp_path, compensated):
    _, result, _ = compensated
    save_drive(tmp_path / "nis.drive.h5", result.drive, result.to_json())
    text = """name = "compensated"
angles_deg = [{angles}]
records = [
    {{ record = "fema:KOBE/NIS000", window_s = [5.0, 10.0], drive = "nis.drive.h5" }},
]

[[bodies]]
table5 = 4
x = 0.0
y = 0.0
"""
    (tmp_path / "seq.toml").write_text(text.format(angles="4"))
    sequence = load_sequence(tmp_path / "seq.toml")
    run = sequence.plan()[0]
    assert np.array_equal(sequence.prepare(run).poses, result.drive.poses)
    assert sequence.to_dict()["records"][0]["drive"] == str(tmp_path / "nis.drive.h5")
    (tmp_path / "seq.toml").write_text(text.format(angles="4, 5"))
    sequence = load_sequence(tmp_path / "seq.toml")
    with pytest.raises(SequenceError, match=r"seq.toml:4: .*iterated at β = 4°, not 5°"):
        sequence.check()


def test_response_rows_round_trip(compensated):
    _, _, frf = compensated
    back = response_from_rows(response_rows(frf), frf.band)
    assert np.array_equal(back.h, frf.h) and np.array_equal(back.coherence, frf.coherence)


def test_uncompensated_error_of_a_record_against_its_iterations(compensated):
    drive, result, _ = compensated
    assert result.iterations[0].rms_error_pct > 2 * result.iterations[result.best].rms_error_pct
    assert drive.record == result.drive.record


def test_a_mimo_iteration_stored_and_reported(tmp_path):
    """The MIMO law offline, its plays written to a session's /compensation (schema 2) and shown by the report:
    the response matrix, every play's level and measures, the table's new columns."""
    ident = identification_drive(TABLE, BETA, duration=20.0)
    matrix = estimate(ident.accelerations[:, :3], base_accelerations(play_offline(TABLE, ident.poses), BETA),
                      TABLE.controller_rate)
    motion = load_entry(RecordEntry(spec="fema:KOBE/NIS000", resolved="fema:KOBE/NIS000", window=(5.0, 10.0)))
    drive = prepare_drive(motion, angle=BETA, table=TABLE, corner=1.0, settle=0.5, ramps=False, headroom=0.1)
    result = compensate(drive, MimoLaw(matrix), lambda d, k: play_offline(TABLE, d.poses, seed=k), iterations=1)
    path = tmp_path / "s.h5"
    with SessionLog.create(path, rig_config=TABLE.to_dict(), sequence={"name": "t"}, software_version="test"):
        pass
    runs = [f"{k + 2:04d}" for k in range(len(result.iterations))]
    store.write(path, record=drive.record, angle_deg=4.0, identification_run="0001", iteration_runs=runs,
                result=result, t=drive.t, drive_file="")
    stored = store.read(path)
    assert stored["attrs"]["law"] == "mimo" and stored["attrs"]["schema"] == "shaketable-rig/compensation/3"
    rows = stored["iterations"]
    assert list(rows["level_db"]) == [-12.0, -6.0, 0.0]
    assert rows["rms_error_pct"] == pytest.approx([it.rms_error_pct for it in result.iterations])
    assert rows["surge_trac"] == pytest.approx([it.measures.axes["surge"]["trac"] for it in result.iterations])
    assert np.all(rows["peak_to_limit"] <= 1.0) and rows["rms_error_pct"][-1] < rows["rms_error_pct"][0] / 2
    assert np.all(stored["response"]["condition"][stored["response"]["surge_coherence"] > 0.9] >= 1.0)
    with h5py.File(path, "r") as h5:
        assert h5["compensation/response_matrix"].shape == (len(matrix.f), 3, 3)
    html = compensation_section(path)
    assert "TRAC" in html and "mimo" in html and "level [dB]" in html
