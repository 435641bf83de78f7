"""The rig configuration's ``[limit_detectors]`` and a sequence's overrides: read in SI, written back, and bad
input refused with FILE:LINE, the channel and the key (analysis/table/limit_detectors.py)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from analysis.table.controller_limits import controller_levels
from analysis.table.limit_detectors import Detector, G, LimitDetectors
from analysis.table.model import TableModel, TableModelError
from rig.sequence import Sequence, SequenceError, load_sequence

RIG = """\
[table]
controller_rate_hz = 1000

[limit_detectors.accel.x]
warn_high_g = 0.4
abort_high_g = 0.6
abort_low_m_s2 = -5.0
persistence = 3
action = "emergency_stop"

[limit_detectors.tilt.angle]
warn_high_deg = 20
"""


def write(tmp_path: Path, text: str, name: str = "rig.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_levels_are_read_in_si_and_written_back(tmp_path: Path) -> None:
    model = TableModel.from_toml(write(tmp_path, RIG))
    accel, tilt = model.detectors.detectors
    assert accel == Detector("accel.x", abort_low=-5.0, warn_high=0.4 * G, abort_high=0.6 * G, persistence=3,
                             action="emergency_stop")
    assert accel.where == f"{tmp_path / 'rig.toml'}:4"
    assert tilt == Detector("tilt.angle", warn_high=math.radians(20))  # default: persistence 1, controlled stop
    assert TableModel.from_dict(model.to_dict()).detectors == model.detectors
    assert "limit_detectors" not in TableModel().to_dict()


def test_a_leg_s_following_error_takes_levels_in_mm(tmp_path: Path) -> None:
    model = TableModel.from_toml(write(tmp_path, "[limit_detectors.leg.following_error]\nabort_high_mm = 5\n"
                                                 "abort_low_mm = -5\n"))
    assert model.detectors.detectors == (Detector("leg.following_error", abort_low=-0.005, abort_high=0.005),)


def test_the_link_s_age_takes_high_levels_in_s_or_ms_and_is_never_downloaded(tmp_path: Path) -> None:
    model = TableModel.from_toml(write(tmp_path, "[limit_detectors.link.age]\nwarn_high_ms = 100\n"
                                                 "abort_high_s = 0.2\npersistence = 3\n"))
    assert model.detectors.detectors == (Detector("link.age", warn_high=0.1, abort_high=0.2, persistence=3),)
    assert TableModel.from_dict(model.to_dict()).detectors == model.detectors
    assert controller_levels(model.detectors) == ()  # host-only: the controller cannot judge its own link


@pytest.mark.parametrize(("text", "message"), [
    ("[limit_detectors.accel.x]\nwarn_high_g = 0.6\nabort_high_g = 0.4\n",
     r":3: limit_detectors\.accel\.x\.abort_high_g: levels in the wrong order: abort_high \(3\.924 m/s²\) must be "
     r"above warn_high \(5\.886 m/s²\)"),
    ("[limit_detectors.accel.x]\nabort_low_g = 0.5\nabort_high_g = 0.4\n",
     r":3: limit_detectors\.accel\.x\.abort_high_g: levels in the wrong order"),
    ("[limit_detectors.accel.w]\nabort_high_g = 0.4\n",
     r":1: limit_detectors\.accel\.w: unknown key; expected one of x, y, z"),
    ("[limit_detectors.legs.x]\nabort_high_g = 0.4\n",
     r":1: limit_detectors\.legs: unknown key \(did you mean 'leg'\?\); expected one of accel, leg, link, pose, "
     r"tilt, velocity"),
    ("[limit_detectors.leg.following_error]\nabort_high_deg = 2\n",
     r":2: limit_detectors\.leg\.following_error\.abort_high_deg: unit 'deg' does not fit leg\.following_error, a "
     r"length: expected abort_high_m or abort_high_mm"),
    ("[limit_detectors.accel.x]\nabort_high_m = 0.4\n",
     r":2: limit_detectors\.accel\.x\.abort_high_m: unit 'm' does not fit accel\.x, an acceleration: expected "
     r"abort_high_g or abort_high_m_s2"),
    ("[limit_detectors.pose.heave]\nabort_high_deg = 3\n",
     r":2: limit_detectors\.pose\.heave\.abort_high_deg: unit 'deg' does not fit pose\.heave, a length"),
    ("[limit_detectors.accel.z]\nabort_high_g = 30\n",
     r":2: limit_detectors\.accel\.z\.abort_high_g: expected an acceleration within ±20 g"),
    ("[limit_detectors.accel.z]\nabort_high_g = '1'\n",
     r":2: limit_detectors\.accel\.z\.abort_high_g: expected a number in g, got '1'"),
    ("[limit_detectors.accel.z]\nabort_high_g = 1\npersistence = 0\n",
     r":3: limit_detectors\.accel\.z\.persistence: expected a whole number of samples from 1 to 10000, got 0"),
    ("[limit_detectors.accel.z]\nabort_high_g = 1\naction = 'halt'\n",
     r":3: limit_detectors\.accel\.z\.action: expected one of record, pause, controlled_stop, emergency_stop"),
    ("[limit_detectors.accel.z]\npersistence = 2\n",
     r":1: limit_detectors\.accel\.z: no level"),
    ("[limit_detectors.link.age]\nwarn_high_ms = 100\nabort_low_s = 0.01\n",
     r":3: limit_detectors\.link\.age\.abort_low_s: link\.age takes no low level \(a status is never too recent\): "
     r"expected warn_high or abort_high"),
    ("[limit_detectors.link.age]\nabort_high_s = 11\n",
     r":2: limit_detectors\.link\.age\.abort_high_s: expected an age within 0 … 10 s \(above 0\), got 11"),
    ("[limit_detectors.link.age]\nabort_high_ms = 0\n",
     r":2: limit_detectors\.link\.age\.abort_high_ms: expected an age within 0 … 10 s \(above 0\), got 0"),
    ("[controller]\nlink_timeout_s = 0.4\n\n[limit_detectors.link.age]\nabort_high_ms = 400\n",
     r":5: limit_detectors\.link\.age\.abort_high_ms: abort_high \(0\.4 s\) must be below \[controller\] "
     r"link_timeout_s \(0\.4 s\): the link is lost, and the session ends, before it would trip"),
    ("[limit_detectors.link.age]\nabort_high_m = 0.1\n",
     r":2: limit_detectors\.link\.age\.abort_high_m: unit 'm' does not fit link\.age, an age: expected "
     r"abort_high_s or abort_high_ms"),
    ("[limit_detectors.accel.z]\nabort_high_g = 1\nabort_high_m_s2 = 9\n",
     r":3: limit_detectors\.accel\.z\.abort_high_m_s2: abort_high is given twice"),
])
def test_bad_detectors_are_refused_with_the_line_and_the_key(tmp_path: Path, text: str, message: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(TableModelError, match=rf"^{path}{message}"):
        TableModel.from_toml(path)


SEQUENCE = """\
angles_deg = [0]
records = [{{ record = "fema-nearfield:NORTHR/RRS_032", window_s = [0.5, 3.5] }}]

[rig]
config = "rig.toml"

[[bodies]]
table5 = 5
x = 0.0
y = 0.0

{overrides}
"""


def test_a_sequence_overrides_the_rig_s_detectors_channel_by_channel(tmp_path: Path) -> None:
    write(tmp_path, RIG)
    path = write(tmp_path, SEQUENCE.format(overrides="[limit_detectors.accel.x]\nwarn_high_g = 0.2\n"),
                 "sequence.toml")
    sequence = load_sequence(path)
    assert sequence.table.detectors == LimitDetectors((Detector("accel.x", warn_high=0.2 * G),
                                                       Detector("tilt.angle", warn_high=math.radians(20))))
    again = Sequence.from_dict(sequence.to_dict())  # as a session file stores it
    assert again.table.detectors == sequence.table.detectors


def test_a_bad_override_is_refused_with_the_sequence_s_line(tmp_path: Path) -> None:
    write(tmp_path, RIG)
    path = write(tmp_path, SEQUENCE.format(overrides="[limit_detectors.pose.roll]\nwarn_high_m = 0.2\n"),
                 "sequence.toml")
    with pytest.raises(SequenceError, match=rf"^{path}:13: limit_detectors\.pose\.roll\.warn_high_m: unit 'm' does "
                                            "not fit pose.roll, an angle"):
        load_sequence(path)


def test_a_sequence_s_link_age_level_is_checked_against_the_rig_s_link_timeout(tmp_path: Path) -> None:
    write(tmp_path, RIG)  # the default link timeout: 0.5 s
    ok = write(tmp_path, SEQUENCE.format(overrides="[limit_detectors.link.age]\nabort_high_ms = 150\n"), "ok.toml")
    assert Detector("link.age", abort_high=0.15) in load_sequence(ok).table.detectors.detectors
    path = write(tmp_path, SEQUENCE.format(overrides="[limit_detectors.link.age]\nwarn_high_s = 0.6\n"),
                 "sequence.toml")
    with pytest.raises(SequenceError, match=rf"^{path}:13: limit_detectors\.link\.age\.warn_high_s: warn_high "
                                            r"\(0\.6 s\) must be below \[controller\] link_timeout_s \(0\.5 s\)"):
        load_sequence(path)
