"""One iteration session on a table: identify, iterate, store — what ``rig iterate`` runs (``docs/compensation.md``).

The table is armed and tilted to the drive's angle; the identification drive (``identify``) is played as the
session's first run and the frequency response computed from it; the record's drive is then played and corrected
(``iteration.compensate``), every play a run of the session with its error; the table goes home and is disarmed; the
best drive is written as a drive file and the identification and iterations as the session's ``/compensation``.
With the ``mimo`` law (default) the identification gives the response matrix (``rig.compensation.mimo``), with
``diagonal`` the per-axis responses (``rig.compensation.identify``); every play is checked against the predicted
response first and the first plays ramp up in level (``rig.compensation.iteration``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drivers.controller import open_table
from rig.drive import Drive
from rig.drive import file as drive_file
from rig.session import SessionLog

from . import store
from .identify import BAND, frequency_response, identification_drive
from .iteration import BAND_HIGH, Compensation, Law, compensate
from .laws import DiagonalLaw, MimoLaw
from .mimo import estimate
from .safety import LEVELS_DB
from .signals import base_accelerations
from .table_play import TablePlayer

LAWS = ("mimo", "diagonal")
"""The update laws ``rig iterate --law`` offers (``rig.compensation.laws``)."""


@dataclass
class Outcome:
    """What an iteration session produced: the session file, the drive file, the response, the iterations."""

    session: Path
    drive_file: Path
    result: Compensation
    identification_run: str
    runs: list[str]

    def to_json(self) -> dict[str, Any]:
        """``rig iterate --json``: the law, every play (level, errors per axis and along the fall line, TRAC,
        response-spectrum error, peak / limit, run), converged, drive file, session."""
        return {"law": self.result.law,
                "iterations": [{**it.to_json(), "run": run}
                               for it, run in zip(self.result.iterations, self.runs, strict=True)],
                "converged": self.result.converged, "stopped": self.result.stopped, "best": self.result.best,
                "drive": str(self.drive_file), "session": str(self.session),
                "identification_run": self.identification_run}


def iterate_on_table(drive: Drive, url: str, options: dict[str, Any], session: Path, drive_path: Path, *,
                     sequence: dict[str, Any], software_version: str, bodies: list[dict[str, Any]] | None = None,
                     iterations: int = 4, law: str = "mimo", gain: float | None = None, tolerance: float = 0.0,
                     levels_db: tuple[float, ...] = LEVELS_DB, identify_seconds: float = 60.0,
                     band: tuple[float, float] = BAND, band_high: float = BAND_HIGH,
                     note: Callable[[str], None] | None = None) -> Outcome:
    """Identify and iterate ``drive`` on the table at ``url`` (module docstring) into the new ``session`` file."""
    if law not in LAWS:
        raise ValueError(f"law {law!r}: expected one of {', '.join(LAWS)}")
    say = note or (lambda _text: None)
    table_model = drive.table
    ident = identification_drive(table_model, drive.angle, duration=identify_seconds, band=band)
    with open_table(url, **{"table": table_model, **options}) as table, \
            SessionLog.create(session, rig_config=table_model.to_dict(), sequence=sequence,
                              software_version=software_version) as log:  # a table that refuses leaves no file
        player = TablePlayer(table, log, url, bodies=bodies or [])
        try:
            say(f"tilting to {math.degrees(drive.angle):g}°")
            player.tilt(drive.angle)
            say(f"identification: {ident.duration:.0f} s of band-limited random motion, {band[0]:g}–{band[1]:g} Hz")
            measured = base_accelerations(player.play(ident, "identify", 0), drive.angle)
            update = make_law(law, ident.accelerations[:, :3], measured, drive.rate, band=band, gain=gain,
                              band_high=band_high)
            identification_run = player.runs[-1]
            player.target = drive

            def play(candidate: Drive, index: int) -> Any:
                say(f"iteration {index}: playing {candidate.duration:.0f} s")
                return player.play(candidate, "iterate", index)

            result = compensate(drive, update, play, iterations=iterations, levels_db=levels_db,
                                tolerance=tolerance, band_high=band_high)
        except BaseException:
            _stop_quietly(table)  # a controlled stop home: the iteration cannot go on
            raise
        say("home")
        player.finish()
        runs = player.runs[1:]
    summary = {**result.to_json(), "session": str(session), "runs": runs}
    drive_file.save_drive(drive_path, result.drive, summary)
    store.write(session, record=drive.record, angle_deg=math.degrees(drive.angle),
                identification_run=identification_run, iteration_runs=runs, result=result,
                t=drive.t, drive_file=str(drive_path))
    return Outcome(session, drive_path, result, identification_run, runs)


def make_law(name: str, commanded: np.ndarray, measured: np.ndarray, rate: float, *, band: tuple[float, float],
             gain: float | None = None, band_high: float = BAND_HIGH) -> Law:
    """The update law ``name`` (``mimo`` or ``diagonal``, ``rig.compensation.laws``) with its response identified
    from the identification play's commanded and measured base-frame accelerations (n, 3) [m/s²]; ``gain`` its
    gain (None: the law's default)."""
    if name == "mimo":
        mimo = estimate(commanded, measured, rate, band=band)
        if gain is None:
            return MimoLaw(mimo, band_high=band_high)
        return MimoLaw(mimo, band_high=band_high, gain=gain, gain_high=gain * MimoLaw.gain_high / MimoLaw.gain)
    if name == "diagonal":
        diagonal = frequency_response(commanded, measured, rate, band=band)
        return DiagonalLaw(diagonal) if gain is None else DiagonalLaw(diagonal, gain=gain)
    raise ValueError(f"law {name!r}: expected one of {', '.join(LAWS)}")


def _stop_quietly(table: Any) -> None:
    """STOP (decelerate, home) unless the table has stopped already; its errors do not hide the first one."""
    from drivers.controller import TableError

    try:
        if table.status().state in ("armed", "streaming", "tilting", "homing"):
            table.stop()
    except TableError:
        pass
