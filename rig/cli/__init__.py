"""The ``rig`` command line (docs/architecture.md §1, §7): one module per command or command group, each adding
itself with ``register(app)``; what they share (consoles, errors, JSON output, exit codes) is `rig.cli._common`.

``--json`` prints exactly one JSON object on stdout; errors go to stderr with exit code 2 and no
traceback. Angles are in degrees here (radians inside).

Imports are lazy (issue 16): this package and every module in it import only typer, rich, the standard library and
light modules (`rig.emulator` for ``parse_speed``, `analysis.body`) at module level, so that `rig --help` and each
command's --help answer at once; each command imports what it uses inside its body (numpy, scipy, numba, h5py,
matplotlib, … only where needed). tests/rig/test_cli_startup.py checks it.

``rig --version`` prints the version; ``rig --install-completion`` installs tab completion for the shell it runs in
(bash, zsh, fish, PowerShell; ``--show-completion`` prints the script instead), typer's own.
"""

from __future__ import annotations

import sys
from typing import Annotated

import typer

from rig.cli import (
    analyze,
    certs,
    demo,
    design,
    emulate,
    iterate,
    plan,
    prepare,
    records,
    report,
    run,
    serve,
    sessions,
    specimens,
    study,
    table,
)

app = typer.Typer(help="Shake-table rig: records, analysis, studies and design of controlled overturning.",
                  no_args_is_help=True)


def _print_version(asked: bool) -> None:
    if asked:
        from rig import __version__

        typer.echo(f"rig {__version__}")
        raise typer.Exit()


@app.callback()
def _options(version: Annotated[bool, typer.Option("--version", callback=_print_version, is_eager=True,
                                                   help="Print the version and exit.")] = False) -> None:
    """Shake-table rig: records, analysis, studies and design of controlled overturning."""

for command in (study, demo, records, prepare, design, emulate, run, sessions, specimens, serve, analyze, report,
                iterate, plan, certs, table):
    command.register(app)


def main() -> None:
    """The ``rig`` command. When stderr is not a terminal, a usage error is click's plain text (``Error: …`` on one
    line, greppable) instead of typer's rich panel, which wraps at 80 columns."""
    if not sys.stderr.isatty():
        app.rich_markup_mode = None  # read when the command is built (typer.main.get_group)
    app()
