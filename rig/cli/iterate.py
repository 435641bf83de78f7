"""``rig iterate RECORD --angle DEG [--table URL | --emulate]``: identify the table's response, iterate the record's
drive until the plate's achieved acceleration reproduces it, save the compensated drive (``docs/compensation.md``).

Exit codes: 0 done (converged or not: ``converged`` says), 1 the table stopped a run, 2 bad input, 3 the record's
drive does not fit the table, or the plate's predicted response to it does not (nothing of the record played).
"""

from __future__ import annotations

import math
from datetime import datetime
from itertools import pairwise
from pathlib import Path
from typing import Annotated, Any

import typer

from protocols.signing_key import write_signing_key
from rig.cli._common import EXIT_REFUSED, EXIT_STOPPED, console, emit_json, err_console, fail, print_error
from rig.cli.passphrase import KeyPassphrase, use_key_passphrase


def register(app: typer.Typer) -> None:
    """Add ``rig iterate``."""

    @app.command("iterate")
    def iterate_cmd(
        record: Annotated[str, typer.Argument(help="the record (SUITE:NAME, library:NAME, a file, H1+H2[+UP])")],
        angle: Annotated[float, typer.Option(help="plate tilt β in degrees")] = 0.0,
        table: Annotated[str | None, typer.Option(help="the table's URL (mavlink://, zenoh://, canopen://)")] = None,
        emulate: Annotated[bool, typer.Option(help="start the emulated table (MAVLink on loopback)")] = False,
        iterations: Annotated[int, typer.Option(help="full-level plays at most (after the level ramp)")] = 4,
        law: Annotated[str, typer.Option(help="the update law: mimo (response matrix) or diagonal (per axis)")
                       ] = "mimo",
        levels: Annotated[str, typer.Option(help="the first plays' levels in dB, comma-separated, ending at 0")
                          ] = "-12,-6,0",
        headroom: Annotated[str, typer.Option(help="margin the drive's scale leaves on every limit for the "
                                              "corrections, e.g. 10%")] = "10%",
        output: Annotated[Path | None, typer.Option("-o", "--output", help="the new session file (default: "
                                                    "iterate-DATE-RECORD.h5 here)")] = None,
        drive_out: Annotated[Path | None, typer.Option("--drive-out", help="the compensated drive file (default: "
                                                       "SESSION.drive.h5)")] = None,
        gain: Annotated[float | None, typer.Option(help="gain of each correction, 0 to 1.5 (default: the law's, "
                                                   "mimo 1 up to 50 Hz, diagonal 0.8)")] = None,
        tolerance: Annotated[float, typer.Option(help="stop at this fall-line RMS error, percent")] = 0.0,
        identify_seconds: Annotated[float, typer.Option(help="length of the identification drive in seconds")] = 60.0,
        window: Annotated[str | None, typer.Option(help="play only T0,T1 (seconds) of the record")] = None,
        corner: Annotated[float | None, typer.Option(help="a fixed high-pass corner in Hz")] = None,
        rig_config: Annotated[Path | None, typer.Option(help="rig configuration TOML (limits, hexapod, "
                                                        "dynamics section)")] = None,
        dynamics: Annotated[str, typer.Option(help="with --emulate: the legs' model, servo or lag")] = "servo",
        body: Annotated[list[str] | None, typer.Option(help="with --emulate: a specimen BxH@X,Y[;mass=M] on the "
                                                       "plate (repeat)")] = None,
        speed: Annotated[str, typer.Option(help="with --emulate: controller time per real time, or max (virtual "
                                           "time: as fast as the machine computes)")] = "1",
        key_file: Annotated[Path | None, typer.Option(help="signing key file (default: "
                                                      "$SHAKETABLE_MAVLINK_KEY)")] = None,
        as_json: Annotated[bool, typer.Option("--json", help="print one JSON object")] = False,
        key_passphrase: KeyPassphrase = None,
    ) -> None:
        """Identify the table's frequency response, then play, measure and correct the record's drive until the
        plate's fall-line acceleration matches it (each play a run of the session), and save the best drive."""
        use_key_passphrase(key_passphrase, key_file)
        from analysis.table.model import TableModel, TableModelError
        from drivers.controller import TableError
        from rig import __version__
        from rig.compensation.safety import LEVEL_STEP_DB, PredictedLimitError
        from rig.compensation.session import LAWS, iterate_on_table
        from rig.drive import DriveError, DriveRefusedError, parse_headroom, prepare_drive
        from rig.drive.file import DriveFileError
        from rig.records import RecordError
        from rig.sequence.model import RecordEntry
        from rig.sequence.records import load_entry
        from rig.session import SessionError

        if emulate == (table is not None):
            fail("give either --table URL or --emulate")
        if iterations < 1:
            fail(f"--iterations {iterations}: expected >= 1")
        if law not in LAWS:
            fail(f"--law {law!r}: expected one of {', '.join(LAWS)}")
        if gain is not None and not 0 < gain <= 1.5:
            fail(f"--gain {gain!r}: expected a gain in (0, 1.5]")
        try:
            levels_db = tuple(float(v) for v in levels.split(","))
        except ValueError:
            fail(f"--levels {levels!r}: expected levels in dB separated by commas, e.g. -12,-6,0")
        if levels_db[-1] != 0.0 or any(b <= a for a, b in pairwise(levels_db)):
            fail(f"--levels {levels!r}: expected increasing levels in dB ending at 0")
        if dynamics not in ("lag", "servo"):
            fail(f"--dynamics {dynamics!r}: expected servo or lag")
        from rig.emulator import parse_speed

        try:
            speed_factor = parse_speed(speed)
        except ValueError as exc:
            fail(str(exc))
        try:
            model = TableModel.from_toml(rig_config) if rig_config else TableModel()
            span = None
            if window is not None:
                try:
                    t0, t1 = (float(v) for v in window.split(","))
                except ValueError:
                    fail(f"--window {window!r}: expected T0,T1 in seconds")
                span = (t0, t1)
            motion = load_entry(RecordEntry(spec=record, resolved=record, window=span))
            drive = prepare_drive(motion, angle=math.radians(angle), table=model, corner=corner, ramps=False,
                                  headroom=parse_headroom(headroom))
        except DriveRefusedError as exc:
            print_error(err_console, "error", str(exc))
            raise typer.Exit(EXIT_REFUSED) from None
        except (RecordError, DriveError, TableModelError, ValueError) as exc:
            fail(str(exc))
        stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
        safe = "".join(c if c.isalnum() or c in "-_" else "-" for c in motion.name)[:60]
        session = output or Path.cwd() / f"iterate-{stamp}-{safe}.h5"
        drive_path = drive_out or session.with_name(session.name.removesuffix(".h5") + ".drive.h5")
        if drive_path.exists():
            fail(f"{drive_path}: already exists; a drive file is never overwritten (--drive-out)")
        bodies = _bodies(body or [])
        sequence = {"name": f"iterate {motion.name}", "kind": "drive iteration", "record": record,
                    "angles_deg": [angle], "bodies": bodies,
                    "iteration": {"iterations": iterations, "law": law, "gain": gain, "tolerance_pct": tolerance,
                                  "levels_db": list(levels_db), "headroom": drive.headroom,
                                  "identify_seconds": identify_seconds}}
        say = (lambda _t: None) if as_json else (lambda text: console.print(f"[dim]{text}[/]", highlight=False))
        try:
            with _Table(table, emulate, key_file, rig_config, dynamics, body or [], speed_factor) as (url, options):
                outcome = iterate_on_table(drive, url, options, session, drive_path, sequence=sequence,
                                           software_version=__version__, bodies=bodies,
                                           iterations=iterations, law=law, gain=gain, tolerance=tolerance,
                                           levels_db=levels_db, identify_seconds=identify_seconds, note=say)
        except PredictedLimitError as exc:
            print_error(err_console, "error", str(exc))
            if exc.fits_at_db is not None:
                steps = [exc.fits_at_db]
                while steps[-1] + LEVEL_STEP_DB < 0.0:
                    steps.append(steps[-1] + LEVEL_STEP_DB)
                ramp = ",".join(f"{level:g}" for level in [*steps, 0.0])
                again = f"--levels={ramp}" + (" and a new -o file" if output is not None else "")
                print_error(err_console, "hint", f"run it again with {again} ({session.name} keeps this "
                                                 "identification and no play)")
            raise typer.Exit(EXIT_REFUSED) from None
        except (SessionError, DriveFileError, OSError, ValueError) as exc:
            fail(str(exc))
        except TableError as exc:  # the table refused, failed or fell silent: its one line, no traceback
            print_error(err_console, "error", str(exc))
            raise typer.Exit(EXIT_STOPPED) from None
        except RuntimeError as exc:
            print_error(err_console, "error", str(exc))
            raise typer.Exit(EXIT_STOPPED) from None
        if as_json:
            emit_json(outcome.to_json())
            return
        for it, run in zip(outcome.result.iterations, outcome.runs, strict=True):
            m = it.measures
            per_axis = ", ".join(f"{axis} {m.axes[axis]['rms_error_pct']:.1f}" for axis in m.axes)
            trac = m.fall_line["trac"]
            floor = m.noise_floor_pct
            console.print(f"play {it.index} (run {run}, {it.level_db:g} dB): fall-line RMS error "
                          f"{it.rms_error_pct:.1f} %{'' if floor is None else f' (noise floor {floor:.1f} %)'}, "
                          f"peak {it.peak_error_pct:.1f} %, TRAC "
                          f"{'–' if trac is None else f'{trac:.3f}'}, "
                          f"5 % spectrum error ≤ {m.psa_error_max_pct:.1f} %; RMS per axis [%] {per_axis}; peak "
                          f"{m.peak_to_limit:.2f} of the {m.peak_axis} limit", highlight=False)
        console.print(f"{'converged' if outcome.result.converged else 'not converged'}: {outcome.result.stopped}; "
                      f"best play {outcome.result.best}\nsession file: {outcome.session}\n"
                      f"compensated drive: {outcome.drive_file}", highlight=False)


def _bodies(specs: list[str]) -> list[dict[str, Any]]:
    """Session body rows of ``--body`` specs (the emulator's ``BxH@X,Y[;depth=D][;mass=M][;mu=F][;cg=BCG,HCG]``)."""
    from analysis import Body

    rows = []
    for k, spec in enumerate(specs, start=1):
        head, *options = spec.split(";")
        size, _, place = head.partition("@")
        body = Body.parse(size)
        x, y = (float(v) for v in place.split(",")) if place else (0.0, 0.0)
        extra = {name.strip(): float(value) for name, _, value in (o.partition("=") for o in options)
                 if name.strip() != "cg"}  # the centre of gravity: the emulator's, not the session row's
        rows.append({"body_id": k, "name": f"body {k}", "b": body.b, "h": body.h,
                     "depth": extra.get("depth", 2 * body.b), "mass": extra.get("mass", math.nan), "x": x, "y": y})
    return rows


class _Table:
    """The table URL and driver options; with ``emulate`` an emulator process (started here, stopped after)."""

    def __init__(self, url: str | None, emulate: bool, key_file: Path | None, rig_config: Path | None,
                 dynamics: str, bodies: list[str], speed: float) -> None:
        self.url, self.emulate, self.key_file = url, emulate, key_file
        from rig.emulator import speed_flags

        self.flags = ["--dynamics", dynamics, *speed_flags(speed)]
        if rig_config is not None:
            self.flags += ["--rig-config", str(rig_config)]
        for spec in bodies:
            self.flags += ["--body", spec]
        self._emulator: Any = None
        self._scratch: Any = None

    def __enter__(self) -> tuple[str, dict[str, Any]]:
        if not self.emulate:
            if str(self.url).startswith("canopen:"):  # this host is the drives' master: nothing to sign, and the
                return str(self.url), {}              # rig's [drives] and geometry come with the table model
            return str(self.url), ({"key_file": str(self.key_file)} if self.key_file else {})
        import tempfile

        from rig.emulator import EmulatorProcess
        from rig.orchestrator.setup import EMULATOR_LISTEN

        key_file = self.key_file
        if key_file is None:
            self._scratch = tempfile.TemporaryDirectory(prefix="rig-iterate-")
            key_file = Path(self._scratch.name) / "session.key"
            write_signing_key(key_file)
        self._emulator = EmulatorProcess.start(EMULATOR_LISTEN, *self.flags, key_file=key_file)
        return self._emulator.url, {"key_file": str(key_file)}

    def __exit__(self, *exc: object) -> None:
        try:
            if self._emulator is not None:
                self._emulator.stop()
        finally:
            if self._scratch is not None:
                self._scratch.cleanup()
