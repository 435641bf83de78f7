"""`Sequence`: a checked sequence file — its plan of runs, the drive of each run, the check before anything
moves, and its JSON form for the session file (docs/architecture.md §4, §6)."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from analysis.table.model import TableModel
from analysis.table.toml_lines import KeyPath, dotted_path, find_line
from rig.drive import Drive, DriveError, DriveRefusedError, prepare_drive
from rig.drive.tilt import ramp_duration
from rig.records import GroundMotion, RecordError

from .model import DriveOptions, OperatorSteps, PlacedBody, PlannedRun, RecordEntry, SequenceError
from .reader import SCHEMA, read_file, read_mapping
from .records import load_entry


@dataclass(frozen=True, eq=False)
class Sequence:
    """A sequence of runs on the table (see the `rig.sequence` package docstring for the file).

    Attributes:
        name: the sequence's name (default: the file's stem).
        description: free text.
        source: the file it was read from (``<dict>`` from `from_dict`).
        table_url: the table controller's URL (``mavlink://HOST:PORT`` …), or None to give it at run time.
        table: limits, geometry and controller rate the drives are prepared for (default Table IV).
        plate: usable plate size (x, y) [m] the bodies' bases must fit in.
        drive: drive preparation options for every record.
        bodies: the bodies at their places, ``body_id`` 1… in file order.
        angles_deg: plate tilts β [deg], in the order they are run.
        records: the records in the order they are run at each angle.
        repetitions: runs of each record at each angle (≥ 1).
        operator: prompts and confirmations asked of the operator.
    """

    name: str
    description: str
    source: str
    table_url: str | None
    table: TableModel
    plate: tuple[float, float]
    drive: DriveOptions
    bodies: tuple[PlacedBody, ...]
    angles_deg: tuple[float, ...]
    records: tuple[RecordEntry, ...]
    repetitions: int
    operator: OperatorSteps
    lines: dict[KeyPath, int] = field(default_factory=dict, repr=False)
    _motions: dict[int, GroundMotion] = field(default_factory=dict, repr=False)
    _durations: dict[tuple[int, int], float] = field(default_factory=dict, repr=False)

    # ----- construction -----------------------------------------------------------------------------

    @classmethod
    def from_file(cls, path: str | Path) -> Sequence:
        """Read and check a sequence file (types, keys, ranges, placements); see `check` for the rest."""
        fields, lines = read_file(path)
        return cls(source=str(path), lines=lines, **fields)

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str | None = None, base_dir: str | Path | None = None
                  ) -> Sequence:
        """A sequence from the file's layout as a mapping (e.g. `to_dict` read back from JSON).

        ``source`` names it in messages (default: its ``source`` key, else ``<dict>``); relative record files
        are read from ``base_dir`` (default: the working directory).
        """
        base = Path.cwd() if base_dir is None else Path(base_dir)
        if source is None:
            source = data["source"] if isinstance(data.get("source"), str) and data["source"] else "<dict>"
        return cls(source=source, **read_mapping(data, source, {}, base, data.get("name") or "sequence"))

    # ----- the plan ---------------------------------------------------------------------------------

    def plan(self) -> list[PlannedRun]:
        """Every run in playing order: per angle (file order), per record, per repetition."""
        runs: list[PlannedRun] = []
        for a, angle in enumerate(self.angles_deg):
            for r, record in enumerate(self.records):
                for k in range(self.repetitions):
                    runs.append(PlannedRun(len(runs), a, angle, r, record, k))
        return runs

    def error(self, path: KeyPath, problem: str) -> SequenceError:
        """A `SequenceError` at a key of this sequence's file."""
        return SequenceError(self.source, find_line(self.lines, path), dotted_path(path), problem)

    def record_error(self, entry: RecordEntry, problem: str) -> SequenceError:
        """A `SequenceError` at a record's entry."""
        return SequenceError(self.source, entry.line, entry.key, f"{entry.label()}: {problem}")

    # ----- checks -----------------------------------------------------------------------------------

    def standing_problem(self, angle_index: int) -> SequenceError | None:
        """The first body that cannot stand at ``angles_deg[angle_index]`` (β ≥ α, or it slides), else None."""
        angle = self.angles_deg[angle_index]
        for body in self.bodies:
            problem = body.standing_problem(angle)
            if problem:
                return self.error(("angles_deg", angle_index), problem)
        return None

    def motion(self, record_index: int) -> GroundMotion:
        """The record ``records[record_index]`` as it is played (window applied); read once, then cached."""
        if record_index not in self._motions:
            entry = self.records[record_index]
            try:
                self._motions[record_index] = load_entry(entry)
            except RecordError as exc:
                raise self.record_error(entry, str(exc)) from None
        return self._motions[record_index]

    def prepare(self, run: PlannedRun) -> Drive:
        """The run's drive, checked against the table model; refused with the reason when a body cannot stand
        at the run's angle or the drive does not fit the table (`SequenceError` at the key's line). The drive
        starts and ends at the run's tilt: the table is tilted once per angle, before its runs."""
        problem = self.standing_problem(run.angle_index)
        if problem:
            raise problem
        entry = self.records[run.record_index]
        motion = self.motion(run.record_index)
        if entry.drive is not None:
            return self._compensated(entry, entry.drive, run)
        corner = entry.corner if entry.corner is not None else self.drive.corner
        try:
            return prepare_drive(motion, angle=run.angle, table=self.table, scale=entry.scale, corner=corner,
                                 settle=self.drive.settle, ramps=False, headroom=self.drive.headroom)
        except DriveRefusedError as exc:
            raise self.record_error(entry, f"at β = {run.angle_deg:g}° the drive leaves the table: "
                                           f"{exc.violation.message()}") from None
        except DriveError as exc:
            policy = "the fixed scale" if entry.scale is not None else "the drive"
            raise self.record_error(entry, f"at β = {run.angle_deg:g}° {policy} is refused: {exc}") from None

    def _compensated(self, entry: RecordEntry, drive_file: str, run: PlannedRun) -> Drive:
        """The entry's drive file ``drive_file`` (``rig iterate``), checked against the sequence's table and the
        run's angle."""
        from rig.drive.file import DriveFileError, load_drive

        try:
            return load_drive(drive_file, self.table, angle=run.angle)
        except DriveFileError as exc:
            raise self.record_error(entry, f"drive: {exc}") from None
        except DriveRefusedError as exc:
            raise self.record_error(entry, f"drive {entry.drive}: at β = {run.angle_deg:g}° it leaves the table: "
                                           f"{exc.violation.message()}") from None

    def check(self, prepare_drives: bool = True) -> None:
        """Everything before anything moves: every body stands at every angle, every record resolves (and its
        window lies inside it), and — with ``prepare_drives`` — every (record, angle) drive is prepared and
        inside the table. Raises the first problem as a `SequenceError` naming the key and line."""
        for a in range(len(self.angles_deg)):
            problem = self.standing_problem(a)
            if problem:
                raise problem
        for r in range(len(self.records)):
            self.motion(r)
        if prepare_drives:
            self._drive_durations()

    def _drive_durations(self) -> dict[tuple[int, int], float]:
        """Every (angle, record) drive prepared and checked once — the sequence does not change, so a second
        `check` or `table_seconds` does not prepare them again; their durations [s]."""
        for run in self.plan():
            key = (run.angle_index, run.record_index)
            if key not in self._durations:
                self._durations[key] = self.prepare(run).duration
        return self._durations

    def table_seconds(self) -> float:
        """Table time of the whole plan [s]: every run's drive and the tilt moves from level to each angle in turn
        and back (prepares every drive not prepared yet)."""
        durations = self._drive_durations()
        angles = [0.0, *(math.radians(a) for a in self.angles_deg), 0.0]
        tilting = [ramp_duration(abs(b - a), self.table.limits.tilt, self.table.controller_rate)
                   for a, b in itertools.pairwise(angles)]
        return self.repetitions * math.fsum(durations.values()) + math.fsum(tilting)

    # ----- JSON -------------------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """The sequence as plain JSON types in the file's layout (records expanded, file paths absolute, the rig
        configuration inline): the session file's root attribute ``sequence``; `from_dict` reads it back."""
        out: dict[str, Any] = {"schema": SCHEMA, "source": self.source, "name": self.name,
                               "description": self.description}
        if self.table_url is not None:
            out["table_url"] = self.table_url
        out.update({
            "repetitions": self.repetitions,
            "angles_deg": list(self.angles_deg),
            "records": [entry.to_dict() for entry in self.records],
            "bodies": [body.to_dict() for body in self.bodies],
            "rig": self.table.to_dict(),
            "plate": {"size_m": list(self.plate)},
            "drive": self.drive.to_dict(),
            "operator": self.operator.to_dict(),
        })
        return out


def load_sequence(path: str | Path) -> Sequence:
    """Read a sequence file and check its types, keys, ranges and placements (`Sequence.check` does the rest).

    Raises:
        SequenceError: ``FILE:LINE: key.path: what is wrong, expected …``.
    """
    return Sequence.from_file(path)
