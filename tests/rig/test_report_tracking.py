"""The session report shows what a table engineer looks for (issue 22, item 5): the commanded trace visible over the
measured one, per run the fall-line acceleration error (measured − commanded) with its RMS and peak, the plate
pose, the legs' strokes against their limits, and the run's faults and (degraded-state) events.

Truth: the error of a synthetic run whose measured fall-line acceleration is the commanded one plus E sin(2π f t)
(RMS E/√2 over whole periods, peak E); the legs' lengths from the hexapod's joints by hand (|p + (0, 0, h₀) − b| at
home), not from the model's kinematics.
"""

from __future__ import annotations

import base64
import io
import math
import re
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from analysis.body import G
from analysis.table.model import TableModel
from rig.report import figures, write_report
from rig.report.tracking import fall_line_error, leg_strokes
from rig.session import SessionLog

BETA = math.radians(4.0)
A, F_CMD = 0.02, 1.5  # commanded surge amplitude [m] and frequency [Hz]
E, F_ERR = 0.3, 4.0  # the error's amplitude [m/s²] and frequency [Hz]
T_END = 4.0  # whole periods of both


def commanded_rows(rate: float = 1000.0) -> np.ndarray:
    t = np.arange(0.0, T_END + 0.5 / rate, 1.0 / rate)
    rows = np.zeros((t.size, 7))
    rows[:, 0], rows[:, 1], rows[:, 5] = t, A * np.sin(2 * np.pi * F_CMD * t), BETA
    return rows


def accelerometer(commanded: np.ndarray, error_amplitude: float) -> np.ndarray:
    """Plate-frame specific force of a plate whose fall-line acceleration is the commanded one plus the error:
    f_x = a_fl − G sin β (``docs/table-controller.md``: at rest f = (−G sin β, 0, G cos β))."""
    t = commanded[:, 0]
    a_surge = -A * (2 * np.pi * F_CMD) ** 2 * np.sin(2 * np.pi * F_CMD * t)
    a_fl = a_surge * math.cos(BETA) + error_amplitude * np.sin(2 * np.pi * F_ERR * t)
    return np.column_stack([t, a_fl - G * math.sin(BETA), np.zeros_like(t), np.full_like(t, G * math.cos(BETA))])


def test_fall_line_error_rms_and_peak_match_the_closed_form() -> None:
    commanded = commanded_rows()
    error = fall_line_error(commanded, {"0": accelerometer(commanded, E)}, BETA)
    assert error is not None
    inner = slice(200, -200)  # the central differences' end samples are first-order
    assert np.sqrt(np.mean(error.error[inner] ** 2)) == pytest.approx(E / math.sqrt(2), rel=0.01)
    assert error.peak == pytest.approx(E, rel=0.02)
    assert error.rms == pytest.approx(E / math.sqrt(2), rel=0.03)
    a_fl_peak = A * (2 * np.pi * F_CMD) ** 2 * math.cos(BETA)
    assert error.rms_commanded == pytest.approx(a_fl_peak / math.sqrt(2), rel=0.01)
    exact = fall_line_error(commanded, {"0": accelerometer(commanded, 0.0)}, BETA)
    assert exact is not None and exact.rms < 0.01 * E  # a table that follows exactly: (almost) no error


def test_leg_strokes_at_home_are_the_hexapods_joint_distances() -> None:
    model = TableModel()
    g = model.geometry
    pose = np.zeros((5, 7))
    pose[:, 0] = np.linspace(0.0, 1.0, 5)
    legs = leg_strokes(pose, model.to_dict())
    assert legs is not None
    home = np.array([0.0, 0.0, g.home_height])
    by_hand = np.linalg.norm(np.asarray(g.platform_joints) + home - np.asarray(g.base_joints), axis=1)
    np.testing.assert_allclose(legs.lengths, np.tile(by_hand, (5, 1)), rtol=1e-12)
    margins = {"leg_min": by_hand.min() - g.leg_min, "leg_max": g.leg_max - by_hand.max()}
    limit = min(margins, key=margins.__getitem__)
    assert legs.margin == pytest.approx(margins[limit]) and legs.closest[1] == limit
    assert (legs.leg_min, legs.leg_max) == (g.leg_min, g.leg_max)


def test_the_commanded_trace_is_drawn_over_the_measured_one() -> None:
    """Where the table follows the drive exactly the two traces coincide: the commanded one must still be seen."""
    drawer = figures.RunFigure(np.array([0.1, 0.5, 1.0]))
    t = np.linspace(0.0, 4.0, 4001)
    a = 3.0 * np.sin(2 * np.pi * t)
    png = drawer.render(t, a, t, a, None, None)
    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float)
    colour = np.array([int(drawer.cmd.get_color()[k:k + 2], 16) for k in (1, 3, 5)], dtype=float)
    seen = int((np.abs(rgb - colour).sum(axis=2) < 40).sum())
    assert drawer.cmd.get_zorder() > drawer.meas.get_zorder()
    assert seen > 300, f"{seen} pixels of the commanded colour"


def make_session(path: Path) -> Path:
    """One run: the synthetic drive and measurement above, the measured pose at home tilted by β, a fault and two
    events (a degraded state, a control request)."""
    commanded = commanded_rows()
    with SessionLog.create(path, TableModel().to_dict(), {"name": "tracking", "bodies": []}, "test") as log:
        run = log.begin_run(0, record="synthetic", scale_factor=1.0, angle_deg=math.degrees(BETA),
                            commanded=commanded, bodies=[], sensors=["0"])
        force = accelerometer(commanded, E)
        run.append_accel("0", force[:, 0], force[:, 1:])
        t_pose = np.arange(0.0, T_END, 0.02)
        pose = np.zeros((t_pose.size, 6))
        pose[:, 0], pose[:, 4] = A * np.sin(2 * np.pi * F_CMD * t_pose), BETA
        run.append_pose(t_pose, pose)
        errors = np.zeros((t_pose.size, 6))
        errors[7] = [0.1e-3, -0.2e-3, 0.3e-3, 0.4e-3, -0.5e-3, 6e-3]  # leg 6 lags 6 mm once
        run.append_following_error(t_pose, errors)
        run.add_fault(1.25, "UNDERRUN", "buffer ran dry")
        run.add_event(1.3, "degraded: the setpoint buffer ran dry for 12 ms")
        run.add_event(float("nan"), "pause requested (console)")
        run.end("completed", underruns=1, events=[{"t": 2.5, "text": "degraded: accelerometer 0 lost 3 batches"},
                                                  "degraded: the link's delay rose to 40 ms"])
    return path


def test_the_report_shows_error_pose_legs_faults_and_events(tmp_path: Path) -> None:
    session = make_session(tmp_path / "s.h5")
    html = write_report(session, tmp_path / "s.html").output.read_text()
    found = re.search(r"fall-line error RMS <b>([0-9.e+-]+) m/s²</b>.*?peak <b>([0-9.e+-]+) m/s²</b>", html)
    assert found is not None
    assert float(found.group(1)) == pytest.approx(E / math.sqrt(2), rel=0.03)
    assert float(found.group(2)) == pytest.approx(E, rel=0.02)
    for text in ("closest to a stroke limit: leg", "(d) the legs", "(e) plate translations", "UNDERRUN",
                 "buffer ran dry", "degraded: the setpoint buffer ran dry for 12 ms", "pause requested (console)",
                 "degraded: accelerometer 0 lost 3 batches", "degraded: the link&#x27;s delay rose to 40 ms",
                 "Events", "peak following error per leg 1–6 [mm]: 0.10 0.20 0.30 0.40 0.50 6.00"):
        assert text in html, text
    pngs = re.findall(r'src="data:image/png;base64,([^"]*)"', html)
    assert len(pngs) == 2  # the run's acceleration and spectra, and how the table followed it
    tracking = Image.open(io.BytesIO(base64.b64decode(pngs[1]))).convert("L")
    assert tracking.height > 400 and np.asarray(tracking).std() > 10
