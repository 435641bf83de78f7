"""``--key-passphrase`` beside ``--key-file``: the rig's key given as a passphrase, SHA-256 of it as ArduPilot's tools
derive it (``protocols.signing_key.key_from_passphrase``), so that the rig and a ground station (MAVProxy's
``signing setup PASSPHRASE``) sign with the same key.

The key is put in ``$SHAKETABLE_MAVLINK_KEY`` of this process, as 64 hexadecimal digits, where every reader of the
rig's key and the processes ``rig`` starts (the emulator, the console, a service) find it. The passphrase may come from
``$SHAKETABLE_KEY_PASSPHRASE`` instead of the command line (which other users may see in ``ps``).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated

import typer

from rig.cli._common import fail

PASSPHRASE_ENV = "SHAKETABLE_KEY_PASSPHRASE"
"""Environment variable that may hold the passphrase instead of ``--key-passphrase``."""

PASSPHRASE_HELP = (f"the rig's key as a passphrase (key = SHA-256 of it, as MAVProxy's signing setup; ≥ 20 "
                   f"characters; or ${PASSPHRASE_ENV}); instead of --key-file")
"""The help of ``--key-passphrase``, on every command that takes ``--key-file``."""

KeyPassphrase = Annotated[str | None, typer.Option("--key-passphrase", envvar=PASSPHRASE_ENV, metavar="TEXT",
                                                   show_envvar=False, help=PASSPHRASE_HELP)]


def use_key_passphrase(passphrase: str | None, key_file: Path | None) -> None:
    """With a passphrase, its key becomes this process's ``$SHAKETABLE_MAVLINK_KEY`` (module docstring); exits 2
    when it is too weak or given together with ``key_file``."""
    from protocols.signing_key import KEY_ENV, SigningKeyError, key_from_passphrase

    if passphrase is None:
        return
    if key_file is not None:
        fail("--key-passphrase with --key-file: give the rig's key one way")
    try:
        os.environ[KEY_ENV] = key_from_passphrase(passphrase).hex()
    except SigningKeyError as exc:
        fail(str(exc))
