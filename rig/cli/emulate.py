"""``rig emulate --listen URL [options]``: run the table emulator in the foreground.

URL: ``mavlink://127.0.0.1:PORT``, ``zenoh://127.0.0.1:PORT/TABLE`` or ``canopen://CHANNEL?interface=…``. The
signing key (``--key-file FILE`` or ``$SHAKETABLE_MAVLINK_KEY``) is needed on mavlink and zenoh only: CANopen has no
authentication (the bus is a private cable), and the emulator asks for no key there.

The emulator is its own program (``python -m sim_table``, docs/architecture.md §5: a separate process that speaks the
controller's transports), and ``rig`` does not import it: this command runs it as a child process with every
option passed on unchanged. Ctrl-C (SIGINT) on a terminal reaches the emulator directly (and SIGINT or SIGTERM sent
to this process is passed on): it stops cleanly and hands over its counters, printed here as a table (``--json``:
the emulator's one JSON object as it is; ``--counters FILE``: written there, nothing printed). ``rig emulate
--help`` shows the emulator's options (``python -m sim_table --help-json``) in the style of every other command.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import typer

from rig.cli._common import console, fail
from rig.cli.passphrase import PASSPHRASE_ENV, PASSPHRASE_HELP, use_key_passphrase

_EMULATOR = [sys.executable, "-m", "sim_table"]

HELP = ("Run the table emulator (python -m sim_table) in the foreground until Ctrl-C, then print its counters as a "
        "table.")


def register(app: typer.Typer) -> None:
    """Add ``emulate`` to the main application."""
    app.command("emulate", add_help_option=False,
                context_settings={"allow_extra_args": True, "ignore_unknown_options": True}, help=HELP,
                )(emulate_cmd)


def emulate_cmd(ctx: typer.Context) -> None:
    """Run ``python -m sim_table`` with the given options (module docstring)."""
    args = list(ctx.args)
    if {"-h", "--help"} & set(args):
        print_help()
        raise typer.Exit()
    as_json = "--json" in args
    args = take_key_passphrase([a for a in args if a != "--json"])
    sys.stdout.flush()
    sys.stderr.flush()
    proc = subprocess.Popen([*_EMULATOR, *args], stdout=subprocess.PIPE, text=True)  # stderr: the emulator's own

    def pass_on(signum: int, frame: object) -> None:
        if proc.poll() is None:
            proc.send_signal(signum)

    previous = {s: signal.signal(s, pass_on) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        out, _ = proc.communicate()
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    if proc.returncode != 0:
        raise typer.Exit(proc.returncode)
    if not out.strip():  # --counters FILE: written there
        return
    if as_json:
        sys.stdout.write(out)
        return
    print_counters(json.loads(out), console)


def take_key_passphrase(args: list[str]) -> list[str]:
    """``args`` without ``--key-passphrase TEXT`` (or ``--key-passphrase=TEXT``), whose key (else the one of
    ``$SHAKETABLE_KEY_PASSPHRASE``) becomes ``$SHAKETABLE_MAVLINK_KEY``, where the emulator reads the rig's key
    (``rig.cli.passphrase``); exits 2 when the option has no value, the passphrase is too weak or ``--key-file`` is
    given too."""
    rest: list[str] = []
    passphrase = os.environ.get(PASSPHRASE_ENV) or None
    words = iter(args)
    for word in words:
        if word == "--key-passphrase":
            passphrase = next(words, None)
            if passphrase is None or passphrase.startswith("--"):
                fail("--key-passphrase: expected the passphrase after it")
        elif word.startswith("--key-passphrase="):
            passphrase = word.removeprefix("--key-passphrase=")
        else:
            rest.append(word)
    key_files = [word for word in rest if word == "--key-file" or word.startswith("--key-file=")]
    use_key_passphrase(passphrase, Path(key_files[0]) if key_files else None)
    return rest


def print_counters(counters: dict[str, Any], console: Any) -> None:
    """The emulator's counters as a table, and its overturns as another (when it had any)."""
    from rich import box
    from rich.table import Table

    from rig.emulator import counter_rows, overturn_rows

    table = Table(box=box.SIMPLE_HEAD, title="the emulator's counters")
    table.add_column("counter")
    table.add_column("value", justify="right")
    for name, value in counter_rows(counters):
        table.add_row(name, value)
    console.print(table)
    rows = overturn_rows(counters)
    if rows:
        overturns = Table(box=box.SIMPLE_HEAD, title="overturns")
        for name in ("event", "body", "direction", "t [s]", "tilt β [°]"):
            overturns.add_column(name, justify="right")
        for row in rows:
            overturns.add_row(*row)
        console.print(overturns)


def print_help() -> None:
    """The emulator's options (from ``python -m sim_table --help-json``) as the help of a ``rig`` command: a typer
    command with those options is built and asked for its help."""
    import inspect

    described = json.loads(subprocess.run([*_EMULATOR, "--help-json"], capture_output=True, text=True,
                                          check=True).stdout)
    params = []
    for option in described["options"]:
        text = (option["help"] or "").replace("%%", "%") + (" (repeatable)" if option["repeat"] else "")
        if option["choices"]:
            text += f" [{'|'.join(option['choices'])}]"
        annotation: Any = bool if option["switch"] else (list[str] | None if option["repeat"] else str | None)
        default = ... if option["required"] else (False if option["switch"] else option["default"])
        params.append(inspect.Parameter(option["dest"], inspect.Parameter.KEYWORD_ONLY, annotation=annotation,
                                        default=typer.Option(default, *option["flags"], help=text,
                                                             metavar=option["metavar"] or option["dest"].upper(),
                                                             show_default=option["default"] is not None)))
    params.append(inspect.Parameter("as_json", inspect.Parameter.KEYWORD_ONLY, annotation=bool, default=typer.Option(
        False, "--json", help="print the counters as the emulator's one JSON object instead of a table")))
    params.append(inspect.Parameter("key_passphrase", inspect.Parameter.KEYWORD_ONLY, annotation=str | None,
                                    default=typer.Option(None, "--key-passphrase", metavar="TEXT",
                                                         help=PASSPHRASE_HELP)))

    def command(**options: Any) -> None:
        """The emulator's options (never run: only its help is shown)."""

    command.__signature__ = inspect.Signature(params)  # type: ignore[attr-defined]  # typer reads it; typeshed has none
    description = described["description"].replace(", then prints its counters as JSON", "")
    helper = typer.Typer(add_completion=False, rich_markup_mode=None if not sys.stderr.isatty() else "rich")
    helper.command(help=f"{HELP}\n\n{description} Its options are passed on unchanged (it is its own program, "
                        "python -m sim_table).")(command)
    typer.main.get_command(helper).main(["--help"], prog_name="rig emulate", standalone_mode=False)
