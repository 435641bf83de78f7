"""``rig report FILE.h5 -o report.html``: one self-contained HTML report of a session or a study file
(`rig.report`). ``--json`` prints one JSON object (kind, output, bytes, figures, seconds); errors go to stderr
with exit 2."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from rig.cli._common import console, emit_json, fail_with, require_file


def register(app: typer.Typer) -> None:
    """Add ``rig report``."""

    @app.command("report")
    def report_cmd(
        path: Annotated[Path, typer.Argument(metavar="FILE.h5", help="a session file or a study file")],
        output: Annotated[Path | None, typer.Option("-o", "--output", help="the HTML file to write "
                                                    "(default: FILE.html beside the input)")] = None,
        as_json: Annotated[bool, typer.Option("--json", help="print one JSON object")] = False,
    ) -> None:
        """An HTML report (figures embedded, A4 width) of a session (rig, sequence, runs, spectra, detections,
        Fig. 13) or of a study (COR curves, fitted equations, Tables II–III, Fig. 2)."""
        require_file(path)
        target = output if output is not None else path.with_suffix(".html")
        from rig.cli.sessions import crashed_warning
        from rig.report import ReportError, write_report
        from rig.session import SessionError

        try:
            warning = crashed_warning(path)
            if warning:  # the report is written from what is on disk; the file still needs recovering
                sys.stderr.write(warning + "\n")
            if as_json:
                result = write_report(path, target)
            else:
                with console.status(f"writing the report of {path.name}") as status:
                    def progress(done: int, total: int) -> None:
                        status.update(f"writing the report of {path.name}: run {done} of {total}")

                    result = write_report(path, target, progress)
        except (ReportError, SessionError, OSError) as exc:
            fail_with(exc)
        if as_json:
            emit_json(result.as_dict())
            return
        console.print(f"{result.kind} report written to [bold]{result.output}[/] ({result.bytes / 1e6:.1f} MB, "
                      f"{result.figures} figures, {result.seconds:.1f} s)", highlight=False)
