"""``rig demo``: the emulated table runs examples/quick.toml unattended into a new session file, which is then
summarised, analysed (`rig analyze`) and reported (`rig report`).

Exit codes: 0 all runs done, 1 the session stopped early, 2 bad input.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from rig.cli._common import EXIT_STOPPED, emit_json, err_console, fail
from rig.cli._common import console as stdout_console
from rig.cli.run import run_session
from rig.emulator import parse_speed


def register(app: typer.Typer) -> None:
    """Add ``rig demo``."""
    app.command("demo")(demo_cmd)


def demo_cmd(
    output_dir: Annotated[Path, typer.Option("--output-dir", help="where the session file goes")] = Path("demo-output"),
    speed: Annotated[float, typer.Option(parser=parse_speed, metavar="FACTOR|max",
                                         help="the emulator's controller time per real time, or max (virtual "
                                              "time: as fast as it computes)")] = 1.0,
    as_json: Annotated[bool, typer.Option("--json", help="print one JSON object (the files written, the outcome, "
                                          "the emulator's counters, the analysis) on stdout, the rest on stderr")
                       ] = False,
) -> None:
    """The demo: the emulated table (its own process, MAVLink on loopback, two Table V bodies on the plate) runs
    examples/quick.toml unattended; the session file is written, analysed and reported (HTML)."""
    demo(output_dir, speed, as_json=as_json)


QUICK_SEQUENCE = Path(__file__).resolve().parents[2] / "examples" / "quick.toml"
"""The demo's sequence: two Table V bodies, two angles, three short records."""


def demo(output_dir: Path, speed: float, *, as_json: bool = False) -> None:
    """``rig demo``: the emulated table runs the quick sequence unattended into a new session file in
    ``output_dir``; the session and what the emulator itself saw are summarised, the models re-run on the
    measured motion (`rig analyze`), the HTML report written (`rig report`), and the files named (``as_json``: the
    summaries on stderr, one JSON object on stdout)."""
    console = err_console if as_json else stdout_console
    from rig.cli.sessions import print_session
    from rig.emulator import EmulatorError
    from rig.orchestrator.setup import (
        TableChoice,
        create_log,
        default_session_path,
        load_checked,
        table_for,
        write_emulator_counters,
    )
    from rig.sequence import SequenceError
    from rig.session import SessionError

    try:
        sequence = load_checked(QUICK_SEQUENCE)
        output_dir.mkdir(parents=True, exist_ok=True)
        path = default_session_path(sequence, output_dir)
        console.print(f"[bold]shaketable-rig demo[/]: {sequence.name!r} ({len(sequence.plan())} runs, "
                      f"{sequence.table_seconds():.0f} s of table time) on the emulated table over MAVLink "
                      f"(loopback), bodies {', '.join(b.name for b in sequence.bodies)} on the plate")
        with table_for(sequence, None, True, None, speed) as (url, options, counters):
            assert counters is not None
            log = create_log(sequence, path, TableChoice(emulate=True, speed=speed))
            try:
                complete, outcome = run_session(sequence, log, url, options, yes=True, console=console,
                                                with_outcome=True)
            finally:
                log.close()
        emulator_file = write_emulator_counters(path, counters())
    except (SequenceError, SessionError, EmulatorError) as exc:
        fail(str(exc))
    print_session(path, console)
    seen = json.loads(emulator_file.read_text())
    console.print(f"the emulator's specimens overturned {len(seen['overturns'])} times; it counted "
                  f"{seen['underruns']} underruns and {seen['refused_commands']} refused commands")
    from rig.analyze import analyze_session
    from rig.cli.analyze import print_analysis

    console.print("[bold]analysis[/]: both models re-run on the measured plate motion (rig analyze)")
    analysis = analyze_session(path)
    print_analysis(analysis, console)
    from rig.report import write_report

    report = write_report(path, path.with_suffix(".html"))
    console.print(f"session file:      {path}\nemulator counters: {emulator_file}\n"
                  f"report:            {report.output} ({report.figures} figures; open it in a browser)")
    if as_json:
        emit_json({"session": str(path), "complete": complete, **outcome, "emulator_counters": str(emulator_file),
                   "emulator": {key: seen[key] for key in ("overturns", "underruns", "refused_commands")},
                   "report": report.as_dict(), "analysis": analysis.to_json()})
    if not complete:
        raise typer.Exit(code=EXIT_STOPPED)
