"""The orchestrator's download of the abort levels that stop the table (``docs/limits.md``, On the controller),
without a table: what the run's event says when the controller takes them, and the fallback to the host's
detectors said once a session when it cannot (CANopen's master takes none)."""

from __future__ import annotations

from pathlib import Path

from analysis.table.controller_limits import ControllerLevel
from drivers.canopen.table import CanopenTable
from drivers.controller import TableController
from rig.orchestrator import Orchestrator
from rig.sequence import load_sequence
from rig.session import SessionLog
from tests.helpers.sequences import TINY

LEVELS = """
[limit_detectors.accel.x]
warn_high_g = 0.03
abort_high_g = 0.05
persistence = 3

[limit_detectors.accel.z]
abort_low_g = 0.5
action = "emergency_stop"

[limit_detectors.pose.heave]
abort_high_mm = 100
"""


class Controller:
    """A table's download: takes the levels (``refusal`` None) or says why not; keeps what it was given."""

    def __init__(self, refusal: str | None) -> None:
        self.refusal = refusal
        self.given: list[tuple[ControllerLevel, ...]] = []

    def download_limits(self, levels: tuple[ControllerLevel, ...]) -> str | None:
        self.given.append(levels)
        return self.refusal


def orchestrator(tmp_path: Path, controller_limits: bool = True) -> Orchestrator:
    path = tmp_path / "limits.toml"
    path.write_text(TINY + LEVELS)
    sequence = load_sequence(path)
    log = SessionLog.create(tmp_path / "s.h5", rig_config=sequence.table.to_dict(), sequence=sequence.to_dict(),
                            software_version="test")
    return Orchestrator(sequence, "mavlink://127.0.0.1:9", log, controller_limits=controller_limits)


def test_the_levels_that_stop_the_table_are_downloaded_before_each_run(tmp_path: Path) -> None:
    runner, table = orchestrator(tmp_path), Controller(None)
    said = [runner._download_limits(table) for _ in range(2)]  # type: ignore[arg-type]
    assert said == ["limit detectors on the controller: accel.x abort high 0.4905 m/s², accel.z abort low "
                    "4.905 m/s², pose.heave abort high 0.1 m"] * 2
    assert table.given[0] == (ControllerLevel("accel.x", "abort_high", 0.05 * 9.81, 3, "controlled_stop"),
                              ControllerLevel("accel.z", "abort_low", 0.5 * 9.81, 1, "emergency_stop"),
                              ControllerLevel("pose.heave", "abort_high", 0.1, 1, "controlled_stop"))


def test_a_controller_that_cannot_take_them_leaves_the_host_to_act_said_once(tmp_path: Path) -> None:
    runner = orchestrator(tmp_path)
    table = Controller("the controller refused SET_LIMIT: SET_LIMIT failed (MAV_RESULT_UNSUPPORTED)")
    first, second = (runner._download_limits(table) for _ in range(2))  # type: ignore[arg-type]
    assert first == ("limit detectors on the host only (the controller refused SET_LIMIT: SET_LIMIT failed "
                     "(MAV_RESULT_UNSUPPORTED)): an abort level stops the table when the host sees the crossing, up "
                     "to a status batch and a command later")
    assert runner.progress.message == first  # the status line says it too
    assert second is None and len(table.given) == 2  # tried before every run, said once a session


def test_host_only_as_asked_downloads_nothing(tmp_path: Path) -> None:
    runner, table = orchestrator(tmp_path, controller_limits=False), Controller(None)
    said = runner._download_limits(table)  # type: ignore[arg-type]
    assert said is not None and said.startswith("limit detectors on the host only (host only, as asked)")
    assert table.given == []


def test_canopen_s_master_takes_no_levels() -> None:
    assert CanopenTable.download_limits is TableController.download_limits
    level = ControllerLevel("accel.x", "abort_high", 1.0, 1, "controlled_stop")
    taken = TableController.download_limits(None, (level,))  # type: ignore[arg-type]
    assert taken == "this transport does not take limit levels"
