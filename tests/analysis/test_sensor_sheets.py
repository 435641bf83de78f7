"""The ``[sensors]`` table of the rig configuration (analysis/table/sensors.py): sheets read with their units,
bad input refused with FILE:LINE and the key, overdue sensors found, the sheet kept through the JSON layout."""

from __future__ import annotations

from datetime import date
from pathlib import Path

import numpy as np
import pytest

from analysis.body import G
from analysis.table.configuration import configuration_dict, configuration_from_dict, read_configuration
from analysis.table.limits import TableModelError
from analysis.table.sensors import clipped_rows, overdue
from tests.helpers.sensor_sheets import accelerometer, sensors_toml, tilt_sensor, write_rig

ACCELEROMETER = accelerometer(0, model="PCB 356A16", serial="LW231455", range=5.0, calibrated=date(2026, 1, 15),
                              due=date(2027, 1, 15), place_m=[0.30, -0.20, 0.05], axes=["+x", "-y", "+z"],
                              noise_floor_m_s2=0.03)
SHEET = sensors_toml(ACCELEROMETER, overdue="refuse")


def test_a_sheet_is_read_in_si_and_kept_through_the_json_layout(tmp_path: Path) -> None:
    configuration = read_configuration(write_rig(tmp_path, SHEET))
    sheets = configuration.sensors
    assert sheets.overdue == "refuse"
    sheet = sheets.sheets["0"]
    assert sheet.range_m_s2 == pytest.approx(5.0 * G)
    assert (sheet.calibrated, sheet.due) == (date(2026, 1, 15), date(2027, 1, 15))
    assert sheet.place_m == (0.30, -0.20, 0.05) and sheet.axes == ("+x", "-y", "+z")
    assert sheet.noise_floor_m_s2 == 0.03
    assert (sheet.source, sheet.due_line) == (str(tmp_path / "rig.toml"), 12)
    stored = configuration_dict(configuration)
    assert stored["sensors"]["0"]["due"] == "2027-01-15"
    assert configuration_from_dict(stored) == configuration


def _assert_refused(path: Path, line: int, key: str, words: str) -> None:
    """Reading the rig configuration at ``path`` is refused on one line: ``PATH:LINE: KEY: `` and then ``words``."""
    with pytest.raises(TableModelError) as caught:
        read_configuration(path)
    message = str(caught.value)
    assert message.startswith(f"{path}:{line}: {key}: "), message
    assert words in message and "\n" not in message


@pytest.mark.parametrize(("old", "new", "line", "key", "words"), [
    ("due = 2027-01-15", 'due = "next spring"', 12, "sensors.0.due", "expected a date"),
    ("due = 2027-01-15", "due = 2027-01-15T10:00:00", 12, "sensors.0.due", "expected a date"),
    ("due = 2027-01-15", "due = 2025-01-15", 12, "sensors.0.due", "not after the calibration date"),
    ('range_unit = "g"', 'range_unit = "mm"', 10, "sensors.0.range_unit", "expected an acceleration unit"),
    ('sensitivity_unit = "mV/g"', 'sensitivity_unit = "mV/rad"', 8, "sensors.0.sensitivity_unit",
     "sensitivity unit"),
    ("range = 5.0", "range = 5000.0", 9, "sensors.0.range", "full scale from"),
    ('axes = ["+x", "-y", "+z"]', 'axes = ["+x", "+x", "+z"]', 14, "sensors.0.axes", "each of x, y, z once"),
    ("place_m = [0.3, -0.2, 0.05]", "place_m = [30, 0, 0]", 13, "sensors.0.place_m", "within ±20 m"),
    ("noise_floor_m_s2 = 0.03", "noise_floor_m_s2 = 3.0", 15, "sensors.0.noise_floor_m_s2",
     "a noise floor from 1e-06 to 1 m/s² RMS"),
    ("noise_floor_m_s2 = 0.03", "noise_floor_m_s2 = 0.0", 15, "sensors.0.noise_floor_m_s2", "a noise floor from"),
    ("noise_floor_m_s2 = 0.03", 'noise_floor_m_s2 = "low"', 15, "sensors.0.noise_floor_m_s2", "a noise floor from"),
    ('overdue = "refuse"', 'overdue = "ignore"', 2, "sensors.overdue", "expected one of warn, refuse"),
    ("[sensors.0]", "[sensors.front]", 4, "sensors.front", "accelerometer id"),
    ('serial = "LW231455"\n', "", 4, "sensors.0", "missing serial"),
])
def test_bad_input_is_refused_with_file_line_and_key(tmp_path: Path, old: str, new: str, line: int, key: str,
                                                     words: str) -> None:
    assert old in SHEET
    _assert_refused(write_rig(tmp_path, SHEET.replace(old, new)), line, key, words)


def test_overdue_finds_the_sheets_due_on_or_before_a_day(tmp_path: Path) -> None:
    sheets = read_configuration(write_rig(tmp_path, SHEET)).sensors
    assert overdue(sheets, date(2027, 1, 14)) == []
    assert overdue(sheets, date(2027, 1, 15)) == [sheets.sheets["0"]]
    assert sheets.sheets["0"].overdue_problem() == ("accelerometer 0 (PCB 356A16, serial LW231455) was due for "
                                                    "calibration on 2027-01-15")


def test_a_reading_at_its_full_scale_is_clipped() -> None:
    xyz = np.array([[0.0, 0.0, 9.81], [49.0, 0.0, 0.0], [0.0, -49.0, 0.0], [0.0, 0.0, 48.99]])
    assert clipped_rows(xyz, 49.0).tolist() == [1, 2]


def test_the_noise_floor_may_be_left_out(tmp_path: Path) -> None:
    configuration = read_configuration(write_rig(tmp_path, SHEET.replace("noise_floor_m_s2 = 0.03\n", "")))
    assert configuration.sensors.sheets["0"].noise_floor_m_s2 is None
    assert "noise_floor_m_s2" not in configuration_dict(configuration)["sensors"]["0"]
    assert configuration_from_dict(configuration_dict(configuration)) == configuration


def test_a_noise_floor_at_the_full_scale_is_refused(tmp_path: Path) -> None:
    text = SHEET.replace("range = 5.0", "range = 0.05").replace("floor_m_s2 = 0.03", "floor_m_s2 = 0.6")
    path = write_rig(tmp_path, text)
    with pytest.raises(TableModelError, match=r"rig.toml:15: sensors.0.noise_floor_m_s2: noise floor 0.6 m/s² RMS is "
                                              r"not below the sensor's full scale 0.4905 m/s²$"):
        read_configuration(path)


TILT = tilt_sensor(2, model="Jewell A602", serial="T-0423", range=90.0, calibrated=date(2026, 2, 1),
                   due=date(2027, 2, 1))


def test_a_tilt_sensor_s_sheet_is_read_in_rad_and_kept_through_the_json_layout(tmp_path: Path) -> None:
    configuration = read_configuration(write_rig(tmp_path, sensors_toml(ACCELEROMETER, TILT, overdue="refuse")))
    tilt = configuration.sensors.tilts["2"]
    assert tilt.range_rad == pytest.approx(np.pi / 2)
    assert (tilt.model, tilt.serial, tilt.calibrated, tilt.due) == ("Jewell A602", "T-0423", date(2026, 2, 1),
                                                                   date(2027, 2, 1))
    assert set(configuration.sensors.sheets) == {"0"}  # the tilt table is no accelerometer
    stored = configuration_dict(configuration)
    assert stored["sensors"]["tilt"]["2"] == {"model": "Jewell A602", "serial": "T-0423", "range": pytest.approx(
        np.pi / 2), "range_unit": "rad", "calibrated": "2026-02-01", "due": "2027-02-01"}
    assert configuration_from_dict(stored) == configuration
    sheets = configuration.sensors
    assert overdue(sheets, date(2027, 1, 20)) == [sheets.sheets["0"]]
    assert overdue(sheets, date(2027, 2, 1)) == [sheets.sheets["0"], tilt]
    assert tilt.overdue_problem() == ("the tilt sensor of body 2 (Jewell A602, serial T-0423) was due for calibration "
                                      "on 2027-02-01")


@pytest.mark.parametrize(("old", "new", "line", "key", "words"), [
    ('range_unit = "deg"', 'range_unit = "g"', 5, "sensors.tilt.2.range_unit", "an angle unit, one of deg, rad"),
    ("range = 90.0", "range = 400.0", 4, "sensors.tilt.2.range", "a full scale from 1 to 180 deg"),
    ("due = 2027-02-01", 'due = "soon"', 7, "sensors.tilt.2.due", "expected a date"),
    ("due = 2027-02-01", "due = 2026-01-01", 7, "sensors.tilt.2.due", "not after the calibration date"),
    ("[sensors.tilt.2]", "[sensors.tilt.0]", 1, "sensors.tilt.0", "expected a body id from 1 to 255"),
    ('serial = "T-0423"\n', "", 1, "sensors.tilt.2", "missing serial"),
    ('model = "Jewell A602"', 'model = "Jewell A602"\nplace_m = [0, 0, 0]', 3, "sensors.tilt.2.place_m", "unknown"),
])
def test_a_bad_tilt_sheet_is_refused_with_file_line_and_key(tmp_path: Path, old: str, new: str, line: int, key: str,
                                                             words: str) -> None:
    assert old in TILT
    _assert_refused(write_rig(tmp_path, TILT.replace(old, new)), line, key, words)
