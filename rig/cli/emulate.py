"""``rig emulate --listen URL [options]``: run the table emulator in the foreground.

URL: ``mavlink://127.0.0.1:PORT``, ``zenoh://127.0.0.1:PORT/TABLE`` or ``canopen://CHANNEL?interface=…``. The
signing key (``--key-file FILE`` or ``$SHAKETABLE_MAVLINK_KEY``) is needed on mavlink and zenoh only: CANopen has no
authentication (the bus is a private cable), and the emulator asks for no key there.

The emulator is its own program (``python -m sim_table``, ARCHITECTURE §5: a separate process that speaks the
controller's transports), and ``rig`` does not import it: this command *becomes* it (``exec``), with every option
passed on unchanged, so that Ctrl-C (SIGINT) reaches the emulator directly and stops it cleanly — it then prints
its counters as one JSON object (or writes them to ``--counters FILE``). ``rig emulate --help`` lists the options.
"""

from __future__ import annotations

import os
import sys

import typer


def register(app: typer.Typer) -> None:
    """Add ``emulate`` to the main application."""
    app.command("emulate", add_help_option=False,
                context_settings={"allow_extra_args": True, "ignore_unknown_options": True},
                help="Run the table emulator (python -m sim_table) in the foreground; --help for its options.",
                )(emulate_cmd)


def emulate_cmd(ctx: typer.Context) -> None:
    """Replace this process with ``python -m sim_table`` and the given options."""
    sys.stdout.flush()
    sys.stderr.flush()
    os.execv(sys.executable, [sys.executable, "-m", "sim_table", *ctx.args])
