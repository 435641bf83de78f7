"""``rig certs make DIR --name NAME [--ip ADDRESS] [--dns NAME]``: the lab's CA (made once per directory) and a
certificate and key for one process (`rig.certs`; ``docs/lab-network.md``)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rig.cli._common import console, emit_json, fail


def register(app: typer.Typer) -> None:
    """Add the ``certs`` group to the main application."""
    certs_app = typer.Typer(help="TLS certificates of the lab network (docs/lab-network.md).", no_args_is_help=True)

    @certs_app.command("make")
    def make_cmd(
        directory: Annotated[Path, typer.Argument(metavar="DIR", help="the certificates directory (its CA: ca.pem, "
                                                                      "ca.key, made when absent)")],
        name: Annotated[str, typer.Option(help="the process's name: writes DIR/NAME.pem and DIR/NAME.key")],
        ip: Annotated[list[str] | None, typer.Option(help="an IP address the process is reached at (repeat)")] = None,
        dns: Annotated[list[str] | None, typer.Option(help="a DNS name the process is reached at (repeat)")] = None,
        days: Annotated[int, typer.Option(help="validity [days]")] = 825,
        as_json: Annotated[bool, typer.Option("--json", help="print the files as JSON")] = False,
    ) -> None:
        """Make a certificate and key (mode 0600) for one process, signed by the directory's CA."""
        from rig.certs import CertError, fingerprint, make_identity

        try:
            identity = make_identity(directory, name, addresses=tuple(ip or ()), dns=tuple(dns or ()), days=days)
        except (CertError, OSError) as exc:
            fail(str(exc))
        files = {"ca": str(identity.ca), "certificate": str(identity.certificate), "key": str(identity.key),
                 "made_ca": identity.made_ca, "fingerprint_sha256": fingerprint(identity.certificate)}
        if as_json:
            emit_json(files)
            return
        if identity.made_ca:
            console.print(f"made the lab CA {identity.ca} (its key {directory / 'ca.key'} signs every certificate: "
                          "keep it off the lab machines)", highlight=False, soft_wrap=True, markup=False, emoji=False)
        console.print(f"--tls-ca {identity.ca} --tls-cert {identity.certificate} --tls-key {identity.key}",
                      highlight=False, soft_wrap=True, markup=False, emoji=False)
        console.print(f"SHA-256 fingerprint: {files['fingerprint_sha256']}", highlight=False, soft_wrap=True,
                      markup=False, emoji=False)

    app.add_typer(certs_app, name="certs")
