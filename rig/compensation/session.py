"""One iteration session on a table: identify, iterate, store — what ``rig iterate`` runs (``docs/table-dynamics.md``).

The table is armed and tilted to the drive's angle; the identification drive (``identify``) is played as the
session's first run and the frequency response computed from it; the record's drive is then played and corrected
(``iteration.compensate``), every play a run of the session with its error; the table goes home and is disarmed; the
best drive is written as a drive file and the identification and iterations as the session's ``/compensation``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from drivers.controller import open_table
from rig.drive import Drive
from rig.drive import file as drive_file
from rig.session import SessionLog

from . import store
from .identify import BAND, FrequencyResponse, frequency_response, identification_drive
from .iteration import BAND_HIGH, Compensation, compensate
from .signals import base_accelerations
from .table_play import TablePlayer


@dataclass
class Outcome:
    """What an iteration session produced: the session file, the drive file, the response, the iterations."""

    session: Path
    drive_file: Path
    response: FrequencyResponse
    result: Compensation
    identification_run: str
    runs: list[str]

    def to_json(self) -> dict[str, Any]:
        """``rig iterate --json``: iterations (errors per play, 0 = as prepared), converged, drive file, session."""
        return {"iterations": [{"rms_error_pct": it.rms_error_pct, "peak_error_pct": it.peak_error_pct,
                                "gain": it.gain, "run": run, "seconds": it.seconds, "note": it.note}
                               for it, run in zip(self.result.iterations, self.runs, strict=True)],
                "converged": self.result.converged, "stopped": self.result.stopped, "best": self.result.best,
                "drive": str(self.drive_file), "session": str(self.session),
                "identification_run": self.identification_run}


def iterate_on_table(drive: Drive, url: str, options: dict[str, Any], session: Path, drive_path: Path, *,
                     sequence: dict[str, Any], software_version: str, bodies: list[dict[str, Any]] | None = None,
                     iterations: int = 5, gain: float = 0.8, tolerance: float = 0.0,
                     identify_seconds: float = 60.0, band: tuple[float, float] = BAND, band_high: float = BAND_HIGH,
                     note: Callable[[str], None] | None = None) -> Outcome:
    """Identify and iterate ``drive`` on the table at ``url`` (module docstring) into the new ``session`` file."""
    say = note or (lambda _text: None)
    table_model = drive.table
    ident = identification_drive(table_model, drive.angle, duration=identify_seconds, band=band)
    with SessionLog.create(session, rig_config=table_model.to_dict(), sequence=sequence,
                           software_version=software_version) as log, open_table(url, **options) as table:
        player = TablePlayer(table, log, url, bodies=bodies or [])
        try:
            say(f"tilting to {math.degrees(drive.angle):g}°")
            player.tilt(drive.angle)
            say(f"identification: {ident.duration:.0f} s of band-limited random motion, {band[0]:g}–{band[1]:g} Hz")
            measured = base_accelerations(player.play(ident, "identify", 0), drive.angle)
            response = frequency_response(ident.accelerations[:, :3], measured, drive.rate, band=band)
            identification_run = player.runs[-1]
            player.target = drive

            def play(candidate: Drive, index: int) -> Any:
                say(f"iteration {index}: playing {candidate.duration:.0f} s")
                return player.play(candidate, "iterate", index)

            result = compensate(drive, response, play, iterations=iterations, gain=gain, tolerance=tolerance,
                                band_high=band_high)
        except BaseException:
            _stop_quietly(table)  # a controlled stop home: the iteration cannot go on
            raise
        say("home")
        player.finish()
        runs = player.runs[1:]
    summary = {**result.to_json(), "session": str(session), "runs": runs}
    drive_file.save_drive(drive_path, result.drive, summary)
    store.write(session, record=drive.record, angle_deg=math.degrees(drive.angle),
                identification_run=identification_run, iteration_runs=runs, response=response, result=result,
                t=drive.t, drive_file=str(drive_path))
    return Outcome(session, drive_path, response, result, identification_run, runs)


def _stop_quietly(table: Any) -> None:
    """STOP (decelerate, home) unless the table has stopped already; its errors do not hide the first one."""
    from drivers.controller import TableError

    try:
        if table.status().state in ("armed", "streaming", "tilting", "homing"):
            table.stop()
    except TableError:
        pass
