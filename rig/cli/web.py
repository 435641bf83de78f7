"""The console's options shared by every command that serves it (``rig serve --http``, ``rig console``, ``rig run
--console``): the names browsers reach it at, the tokens file of operators and viewers and its HTTPS certificate
(``docs/console.md``, *From another machine*), and what they become: a ``rig.console.WebAccess``, the options not
given taken from the rig configuration's ``[network.console]`` (``analysis.table.network``)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

if TYPE_CHECKING:  # imported where used (rig --help loads no web server)
    from analysis.table.network import ConsoleSettings
    from rig.console import WebAccess

HttpName = Annotated[list[str] | None, typer.Option("--http-name", metavar="NAME",
                                                    help="console: a DNS name or address browsers reach it at "
                                                         "(repeatable; the Host/Origin checks accept it)")]
TokensOption = Annotated[Path | None, typer.Option("--tokens", metavar="FILE",
                                                   help="console: the tokens file of operators and viewers "
                                                        "(docs/console.md), re-read when it changes")]
HttpsCert = Annotated[Path | None, typer.Option("--https-cert", metavar="FILE",
                                                help="console: its HTTPS certificate (PEM, e.g. rig certs make)")]
HttpsKey = Annotated[Path | None, typer.Option("--https-key", metavar="FILE", help="console: the key of --https-cert")]
HttpsDir = Annotated[Path | None, typer.Option("--https-dir", metavar="DIR",
                                               help="console: serve HTTPS with DIR/console.pem, made on first use "
                                                    "(its fingerprint printed)")]


def web_access(names: list[str] | None, tokens: Path | None, https_cert: Path | None, https_key: Path | None,
               https_dir: Path | None, configured: ConsoleSettings | None = None) -> WebAccess:
    """The options as a ``rig.console.WebAccess`` (its files are checked when the console starts), each one not
    given taken from ``configured`` (``[network.console]``; the HTTPS certificate as a whole: the command line's
    ``--https-*`` when any is given, else the configuration's)."""
    from rig.console import WebAccess

    given = WebAccess(tuple(names or ()), tokens, https_cert, https_key, https_dir)
    if configured is None:
        return given
    https = ((https_cert, https_key, https_dir) if any((https_cert, https_key, https_dir)) else
             (configured.https_cert, configured.https_key, configured.https_dir))
    return WebAccess(given.names or configured.names, tokens or configured.tokens, *https)
