"""The emulated accelerometers sit where the rig's calibration sheets put them, with their axes: a rigid plate's
specific force at the sheet's place (a = a_O + α × r + ω × (ω × r)), in the sensor's own axes, against the closed
form of a rotation about a known axis; the host turns it back into the plate frame with the same sheet."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from analysis.body import G
from analysis.table.model import TableModel
from drivers.feedback import AccelBatch
from drivers.hub import Feedback
from sim_table.accelerometers import Accelerometers, sheet_accelerometers
from sim_table.process import EmulatorConfig
from tests.helpers.sensor_sheets import accelerometer, sensors_toml, write_rig

DT = 1e-3


def _table(tmp_path: Path, *sheets: tuple[int, list[float], list[str]]) -> TableModel:
    """A table with accelerometer sheets (id, place_m, axes)."""
    text = sensors_toml(*(accelerometer(i, place_m=place, axes=axes) for i, place, axes in sheets))
    return TableModel.from_toml(write_rig(tmp_path, text))


def _yaw(omega0: float, alpha: float, steps: int = 12) -> np.ndarray:
    """Poses (steps, 6) of a level plate turning about its vertical axis through the origin: yaw = ω0 t + α t² / 2."""
    t = np.arange(steps) * DT
    poses = np.zeros((steps, 6))
    poses[:, 5] = omega0 * t + 0.5 * alpha * t * t
    return poses


def test_a_sensor_off_the_axis_of_a_turning_plate_reads_the_centripetal_and_tangential_terms(tmp_path: Path) -> None:
    radius, height, omega0, alpha = 0.8, 0.05, 2.0, 3.0
    places, mountings = sheet_accelerometers(_table(tmp_path, (0, [radius, 0.0, height], ["-y", "+x", "+z"])).sensors)
    sensors = Accelerometers(places, DT, mountings=mountings, noise=0.0)
    window = _yaw(omega0, alpha)
    reading = sensors.measure(window)[:, 0, :]  # (k, 3), the sensor's own axes
    omega = omega0 + alpha * np.arange(1, len(window) - 1) * DT  # ω at the inner poses
    # plate frame: ω × (ω × r) = −ω² r along −x, α × r = α r along +y, gravity's reaction +g along z
    plate = np.column_stack([-omega**2 * radius, np.full_like(omega, alpha * radius), np.full_like(omega, G)])
    # its axis 1 points along plate −y, axis 2 along +x, axis 3 along +z
    expected = np.column_stack([-plate[:, 1], plate[:, 0], plate[:, 2]])
    np.testing.assert_allclose(reading, expected, rtol=1e-5, atol=1e-6)
    # the host turns it back into the plate frame with the sheet
    feedback = Feedback()
    feedback.mount(_table(tmp_path, (0, [radius, 0.0, height], ["-y", "+x", "+z"])).sensors)
    with feedback.subscribe("accel") as received:
        feedback.publish_accel(AccelBatch(0, 0, 0, 1_000_000, reading))
        np.testing.assert_allclose(received.get(1.0).samples, plate, rtol=1e-5, atol=1e-6)


def test_a_sensor_on_the_axis_reads_no_centripetal_term(tmp_path: Path) -> None:
    places, mountings = sheet_accelerometers(_table(tmp_path, (0, [0.0, 0.0, 0.3], ["+x", "+y", "+z"])).sensors)
    reading = Accelerometers(places, DT, mountings=mountings, noise=0.0).measure(_yaw(2.0, 0.0))
    np.testing.assert_allclose(reading[:, 0, :], np.tile([0.0, 0.0, G], (10, 1)), atol=1e-9)


def test_the_sheets_place_the_emulated_accelerometers_up_to_the_largest_id(tmp_path: Path) -> None:
    table = _table(tmp_path, (0, [0.3, -0.2, 0.05], ["+x", "-y", "-z"]),
                   (2, [-0.5, 0.4, 0.0], ["+z", "+x", "+y"]))
    places, mountings = EmulatorConfig(listen="mavlink://127.0.0.1:0", key=bytes(32), table=table
                                       ).accelerometer_places()
    np.testing.assert_array_equal(places, [[0.3, -0.2, 0.05], [0.0, 0.0, 0.0], [-0.5, 0.4, 0.0]])
    np.testing.assert_array_equal(mountings[0], np.diag([1.0, -1.0, -1.0]))
    np.testing.assert_array_equal(mountings[1], np.eye(3))  # no sheet: at the centre, along the plate's axes
    np.testing.assert_array_equal(mountings[2] @ [1.0, 2.0, 3.0], [3.0, 1.0, 2.0])
    # without sheets: one accelerometer at the centre, as before
    default = EmulatorConfig(listen="mavlink://127.0.0.1:0", key=bytes(32)).accelerometer_places()
    np.testing.assert_array_equal(default[0], [[0.0, 0.0, 0.0]])


def test_places_given_twice_are_refused(tmp_path: Path) -> None:
    table = _table(tmp_path, (0, [0.3, -0.2, 0.05], ["+x", "+y", "+z"]))
    with pytest.raises(ValueError, match=r"^--accel places accelerometers the rig configuration's \[sensors\] sheets"):
        EmulatorConfig(listen="mavlink://127.0.0.1:0", key=bytes(32), table=table, sensors=((0.0, 0.0, 0.0),))
    with pytest.raises(ValueError, match=r"^--accel-noisy: no accelerometer 1 on the emulated plate \(it has 1: "):
        EmulatorConfig(listen="mavlink://127.0.0.1:0", key=bytes(32), table=table, accel_noisy=(1, 0.0, 1.0))
