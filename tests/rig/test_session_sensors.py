"""Sensor sheets in the session file and a record that describes itself (docs/sensors.md, docs/orchestrator.md):
each accelerometer's sheet on its dataset, a clipped reading flagged in the record and in the analysis, units on
every field, an overdue sensor warned of (or refused) at start, and the file read by pyfive."""

from __future__ import annotations

import json
import re
import warnings
from datetime import date
from pathlib import Path

import h5py
import numpy as np
import pytest
import tomli_w

from analysis.body import G
from analysis.table.configuration import configuration_dict, read_configuration
from analysis.table.model import TableModel
from rig.analyze import analyze_session
from rig.orchestrator import OrchestratorState
from rig.orchestrator.setup import check_sensors
from rig.report.data import read_header
from rig.report.sensors import sensors_table
from rig.report.session_report import session_body
from rig.sequence import SequenceError, load_sequence
from rig.session import SessionLog, read_session
from tests.helpers.sensor_sheets import accelerometer, sensors_toml, tilt_sensor, write_rig
from tests.helpers.sequences import TINY_ONE_RUN, new_log, play

SHEET = accelerometer(0, model="PCB 356A16", serial="LW231455", sensitivity=100.0, sensitivity_unit="mV/g", range=2.0,
                      range_unit="g", calibrated=date(2026, 1, 15), due=date(2027, 1, 15),
                      place_m=[0.30, -0.20, 0.05], axes=["+x", "-y", "+z"])
"""Accelerometer 0's sheet, every value stated: the record and the report show them all."""
BODY = {"body_id": 1, "b": 0.1, "h": 0.5, "depth": 0.1, "mass": 5.0, "x": 0.0, "y": 0.0, "name": "B1"}
RATE = 200.0


def _rig(tmp_path: Path, *before: str, overdue: str | None = None) -> Path:
    """The rig configuration ``rig.toml``: the sheets ``before``, then :data:`SHEET`."""
    return write_rig(tmp_path, sensors_toml(*before, SHEET, overdue=overdue))


def _session(tmp_path: Path, spike: float) -> Path:
    """A session of one completed run, 4 s at `RATE` of a plate at rest on accelerometer 0, and one sample of
    ``spike`` [m/s²] along x at t = 1 s."""
    rig = TableModel(*read_configuration(_rig(tmp_path)))
    path = tmp_path / "session.h5"
    with SessionLog.create(path, rig.to_dict(), {"name": "sheets"}, "9.9.9") as log:
        run = log.begin_run(0, record="test:rest", scale_factor=1.0, angle_deg=0.0, commanded=np.zeros((2, 7)),
                            bodies=[BODY], sensors=["0"], attrs={"rate": RATE, "record_start": 0.0})
        t = np.arange(round(4 * RATE)) / RATE
        xyz = np.zeros((len(t), 3))
        xyz[:, 2] = G
        xyz[round(RATE), 0] = spike
        run.append_accel("0", t, xyz)
        run.end("completed")
    return path


def test_a_reading_at_full_scale_is_flagged_in_the_record_and_the_analysis(tmp_path: Path) -> None:
    path = _session(tmp_path, spike=2.0 * G)
    with h5py.File(path, "r") as h5:
        run = h5["runs/0001"]
        assert json.loads(run.attrs["clipped"]) == {"0": 1}
        events = [text.decode() for text in run["events"]["text"]]
        assert any(text.startswith(f"clipped: accelerometer 0 ax = {2 * G:.4g} m/s²") for text in events), events
    result = analyze_session(path, models=("rocking",), write=True)
    assert result.runs[0].clipped == {"0": 1}
    with h5py.File(path, "r") as h5:
        assert json.loads(h5["runs/0001/analysis"].attrs["clipped"]) == {"0": 1}


def test_a_reading_below_full_scale_is_not_flagged(tmp_path: Path) -> None:
    path = _session(tmp_path, spike=np.nextafter(2.0 * G, 0.0))
    with h5py.File(path, "r") as h5:
        run = h5["runs/0001"]
        assert json.loads(run.attrs["clipped"]) == {"0": 0}
        assert not any(text.startswith(b"clipped") for text in run["events"]["text"])
    assert analyze_session(path, models=("rocking",), write=False).runs[0].clipped == {"0": 0}


def test_the_record_describes_itself(tmp_path: Path) -> None:
    path = _session(tmp_path, spike=0.0)
    with h5py.File(path, "r") as h5:
        assert h5.attrs["software_version"] == "9.9.9"
        assert json.loads(h5.attrs["rig_config"])["sensors"]["0"]["serial"] == "LW231455"
        run = h5["runs/0001"]
        accel = run["accel/0"]
        assert accel.attrs["place_m"].tolist() == [0.30, -0.20, 0.05] and accel.attrs["axes"] == "+x,-y,+z"
        assert accel.attrs["range_m_s2"] == pytest.approx(2.0 * G) and accel.attrs["due"] == "2027-01-15"
        units = json.loads(run.attrs["attribute_units"])
        assert units["rate"] == "Hz" and units["scale_factor"] == "1" and units["angle_deg"] == "deg"
        for name in ("commanded", "pose", "accel/0", "tilt/1", "detections", "bodies", "faults", "events"):
            dataset = run[name]
            fields = dataset.dtype.names or ()
            width = len(fields) if fields else dataset.shape[1]
            columns, units_of = dataset.attrs["columns"].split(","), dataset.attrs["units"].split(",")
            assert len(columns) == len(units_of) == width and all(units_of), name
            if fields:
                assert tuple(columns) == fields, name


def test_pyfive_reads_the_session_files_description(tmp_path: Path) -> None:
    """pyfive (pure Python, no HDF5) reads the root: schema, software version, the rig configuration with the
    sensor sheets. The run groups it cannot read (docs/orchestrator.md, *Readers*; measured by
    benchmarks/session_attribute_storage.py): their headers store attribute phase-change values, and the
    SWMR datasets use data layout message version 4, neither of which pyfive 1.3 reads."""
    import pyfive

    path = _session(tmp_path, spike=0.0)
    with pyfive.File(str(path)) as f:
        attrs = {key: value.decode() if isinstance(value, bytes) else value for key, value in f.attrs.items()}
    assert attrs["schema"] == "shaketable-rig/session/1" and attrs["software_version"] == "9.9.9"
    assert json.loads(attrs["rig_config"])["sensors"]["0"]["place_m"] == [0.30, -0.20, 0.05]


def _sequence(tmp_path: Path, *before: str, overdue: str | None = None) -> Path:
    rig = _rig(tmp_path, *before, overdue=overdue)
    path = tmp_path / "sequence.toml"
    path.write_text(f'name = "sheets"\nangles_deg = [0]\nrecords = [{{ record = "fema-farfield:KOBE/NIS000" }}]\n'
                    f'[rig]\nconfig = "{rig}"\n[[bodies]]\ntable5 = 4\nx = 0.0\ny = 0.0\n')
    return path


def test_an_overdue_sensor_warns_at_start(tmp_path: Path) -> None:
    sequence = load_sequence(_sequence(tmp_path))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_sensors(sequence, date(2027, 1, 14))  # due tomorrow: nothing said
    with pytest.warns(UserWarning, match=r"rig.toml:9: sensors.0.due: accelerometer 0 .* was due for calibration on "
                                         r"2027-01-15: recalibrate it"):
        check_sensors(sequence, date(2027, 1, 15))


def test_an_overdue_sensor_is_refused_where_the_configuration_says_so(tmp_path: Path) -> None:
    sequence = load_sequence(_sequence(tmp_path, overdue="refuse"))
    with pytest.raises(SequenceError, match=r"rig.toml:12: sensors.0.due: .*due for calibration on 2027-01-15; the rig "
                                            r"configuration refuses overdue sensors"):
        check_sensors(sequence, date(2030, 1, 1))


def test_the_sheet_survives_the_session_file(tmp_path: Path) -> None:
    path = _session(tmp_path, spike=0.0)
    with h5py.File(path, "r") as h5:
        stored = json.loads(h5.attrs["rig_config"])
    original = read_configuration(_rig(tmp_path))
    assert TableModel.from_dict(stored).sensors == original.sensors
    assert configuration_dict(original)["sensors"] == stored["sensors"]


def test_the_report_prints_the_sheets_and_the_clipped_samples(tmp_path: Path) -> None:
    path = _session(tmp_path, spike=-2.5 * G)
    html = sensors_table(read_header(path).rig_config, read_header(path).runs)
    row = re.search(r"<tr>.*?LW231455.*?</tr>", html, re.S)
    assert row is not None, html
    cells = re.findall(r"<td[^>]*>(.*?)</td>", row.group(0), re.S)
    assert cells == ["0", "PCB 356A16", "LW231455", "100 mV/g", f"±{2 * G:.4g} (±2 g)", "2026-01-15", "2027-01-15",
                     "0.3, -0.2, 0.05", "+x, -y, +z", "1"]
    assert "LW231455" in session_body(str(path))[1]


TILT_SHEET = tilt_sensor(1, model="Jewell A602", serial="T-0423", range=45.0, range_unit="deg",
                         calibrated=date(2026, 2, 1), due=date(2027, 2, 1))


def _tilt_session(tmp_path: Path, angles: list[float]) -> Path:
    """A session of one completed run whose body 1 (its tilt sensor ±45°) reads ``angles`` [rad] at `RATE`."""
    rig_path = _rig(tmp_path, TILT_SHEET)
    rig = TableModel(*read_configuration(rig_path))
    path = tmp_path / "tilt.h5"
    with SessionLog.create(path, rig.to_dict(), {"name": "sheets"}, "9.9.9") as log:
        run = log.begin_run(0, record="test:rock", scale_factor=1.0, angle_deg=0.0, commanded=np.zeros((2, 7)),
                            bodies=[BODY], sensors=["0"], attrs={"rate": RATE, "record_start": 0.0})
        run.append_tilt(1, np.arange(len(angles)) / RATE, np.array(angles))
        run.end("completed")
    return path


def test_a_tilt_reading_at_its_range_is_flagged_and_the_sheet_stored_and_printed(tmp_path: Path) -> None:
    limit = np.radians(45.0)
    path = _tilt_session(tmp_path, [0.0, 0.2, np.nextafter(limit, 0.0), limit, -limit - 0.1, 0.3])
    with h5py.File(path, "r") as h5:
        run = h5["runs/0001"]
        assert json.loads(run.attrs["tilt_clipped"]) == {"1": 2}
        events = [text.decode() for text in run["events"]["text"]]
        assert (f"clipped: tilt sensor of body 1 angle = {limit:.4g} rad at its full scale ±{limit:.4g} rad "
                "(45°)") in events
        tilt = run["tilt/1"]
        assert tilt.attrs["range_rad"] == pytest.approx(limit) and tilt.attrs["serial"] == "T-0423"
        assert (tilt.attrs["calibrated"], tilt.attrs["due"]) == ("2026-02-01", "2027-02-01")
        assert json.loads(h5.attrs["rig_config"])["sensors"]["tilt"]["1"]["range_unit"] == "rad"
    html = sensors_table(read_header(path).rig_config, read_header(path).runs)
    row = re.search(r"<tr>(?:(?!</tr>).)*T-0423.*?</tr>", html, re.S)
    assert row is not None, html
    cells = re.findall(r"<td[^>]*>(.*?)</td>", row.group(0), re.S)
    assert cells == ["1", "Jewell A602", "T-0423", f"±{limit:.4g} (±45°)", "2026-02-01", "2027-02-01", "2"]
    assert "LW231455" in html  # the accelerometer's table too


def test_an_overdue_tilt_sensor_warns_at_start(tmp_path: Path) -> None:
    sequence = load_sequence(_sequence(tmp_path, TILT_SHEET))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_sensors(sequence, date(2027, 2, 1))  # the accelerometer was due on 2027-01-15, the tilt sensor now
    texts = [str(w.message) for w in caught]
    assert len(texts) == 2 and "sensors.0.due: accelerometer 0" in texts[0]
    assert texts[1] == (f"{tmp_path / 'rig.toml'}:7: sensors.tilt.1.due: the tilt sensor of body 1 (Jewell A602, "
                        "serial T-0423) was due for calibration on 2027-02-01: recalibrate it (docs/sensors.md)")


PLACED = sensors_toml(accelerometer(0, place_m=[0.30, -0.20, 0.05], axes=["-y", "+x", "+z"]),
                      accelerometer(1, place_m=[-0.40, 0.30, 0.0], axes=["+x", "-y", "-z"]))


@pytest.mark.integration  # starts the emulator
def test_the_emulated_sensors_sit_where_their_sheets_say_and_are_recorded_in_the_plate_frame(
        tmp_path: Path, key_file: Path) -> None:
    write_rig(tmp_path, PLACED)
    path = tmp_path / "placed.toml"
    path.write_text(TINY_ONE_RUN + '\n[rig]\nconfig = "rig.toml"\n')
    sequence = load_sequence(path)
    rig = tmp_path / "emulated-rig.toml"
    rig.write_text(tomli_w.dumps(sequence.table.to_dict()))
    log = new_log(sequence, tmp_path / "s.h5")
    try:
        state, _ = play(sequence, log, key_file, emulator_flags=("--rig-config", str(rig)))
    finally:
        log.close()
    assert state is OrchestratorState.DONE
    (run,) = read_session(tmp_path / "s.h5")["runs"]
    assert run["status"] == "completed" and set(run["accel"]) == {"0", "1"}
    assert not [e for e in run["events"] if "not declared" in e["text"]]
    for sensor in ("0", "1"):  # each mounted off the plate's axes (z down for 1), at rest: the plate frame's (0, 0, g)
        rows = run["accel"][sensor]
        rest = rows[rows[:, 0] < 0.2, 1:]
        assert len(rest) > 100
        np.testing.assert_allclose(rest.mean(axis=0), [0.0, 0.0, G], atol=0.02)
