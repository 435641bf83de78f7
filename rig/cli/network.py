"""The lab-network options every zenoh command shares (``--tls-ca``, ``--tls-cert``, ``--tls-key``,
``--insecure-plain-tcp``; ``docs/lab-network.md``) and what they become: a ``protocols.zenoh.LinkSecurity`` for a
zenoh session of this process, and the table driver's options for a ``zenoh://`` table. When none of the three
files is given, the rig configuration's ``[network]`` (``analysis.table.network``) gives them
(:func:`configured_security`): the one of ``--rig-config FILE`` (:func:`network_of`; ``rig serve``, ``rig run`` with
``--resume`` or ``--service``), else that of the sequence's ``[rig] config``."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from rig.cli._common import err_console, fail

if TYPE_CHECKING:  # imported where used (rig --help loads no zenoh)
    from analysis.table.network import NetworkSettings
    from protocols.zenoh import LinkSecurity

TlsCa = Annotated[Path | None, typer.Option("--tls-ca", metavar="FILE",
                                            help="zenoh: the lab's CA certificate; with --tls-cert and --tls-key "
                                                 "links are tls/ with mutual authentication (rig certs make)")]
TlsCert = Annotated[Path | None, typer.Option("--tls-cert", metavar="FILE",
                                              help="zenoh: this process's certificate, signed by the lab's CA")]
TlsKey = Annotated[Path | None, typer.Option("--tls-key", metavar="FILE",
                                             help="zenoh: the private key of --tls-cert (mode 0600)")]
NetworkConfig = Annotated[Path | None, typer.Option("--rig-config", metavar="FILE",
                                                    help="this machine's rig configuration: its [network] is the "
                                                         "zenoh TLS identity when --tls-* are not given")]
Insecure = Annotated[bool, typer.Option("--insecure-plain-tcp",
                                        help="zenoh: allow plain tcp/ endpoints off loopback (nothing encrypted; "
                                             "said in the log and the session's events)")]

INSECURE_NOTE = "link: --insecure-plain-tcp: zenoh links off loopback may be plain text (nothing encrypted)"
"""What a session's events and the log say when plain text off loopback was allowed."""


def link_security(ca: Path | None, cert: Path | None, key: Path | None, insecure: bool) -> LinkSecurity:
    """The options as a ``LinkSecurity`` (the TLS files checked: ``protocols.zenoh.tls.load_tls``); exits 2 with
    the option, the file and what is wrong."""
    from protocols.zenoh import LinkSecurity
    from protocols.zenoh.tls import TlsError, load_tls

    try:
        security = LinkSecurity(load_tls(ca, cert, key), insecure)
    except TlsError as exc:
        fail(str(exc))
    if insecure:
        err_console.print(f"warning: {INSECURE_NOTE}", highlight=False, markup=False, soft_wrap=True)
    return security


def table_options(url: str | None, security: LinkSecurity) -> dict[str, Any]:
    """The zenoh table driver's options for ``security`` (none when it is plain loopback); exits 2 when they are
    given for a table that is not ``zenoh://``."""
    if security.tls is None and not security.insecure:
        return {}
    if url is not None and not url.lower().startswith("zenoh://"):
        fail(f"--tls-ca/--tls-cert/--tls-key and --insecure-plain-tcp apply to a zenoh:// table, not {url}")
    return {"tls": security.tls, "insecure_plain_tcp": security.insecure}


def configured_security(given: LinkSecurity, network: NetworkSettings) -> LinkSecurity:
    """``given`` (the command line's) when it names a TLS identity or ``network`` names none; else the rig
    configuration's ``[network]`` identity, its files checked (``protocols.zenoh.tls.load_tls``) and each problem
    named ``FILE:LINE: network.KEY``; exits 2 when they cannot be used."""
    if given.tls is not None or not network.given:
        return given
    from protocols.zenoh import LinkSecurity
    from protocols.zenoh.tls import TlsError, TlsOptions, load_tls

    try:
        return LinkSecurity(load_tls(network.ca, network.cert, network.key, names=TlsOptions(*network.where)),
                            given.insecure)
    except TlsError as exc:
        fail(str(exc))


def network_of(rig_config: Path | None) -> NetworkSettings | None:
    """The ``[network]`` of the rig configuration ``rig_config`` (``--rig-config``; None when not given); exits 2
    with ``FILE:LINE: network.KEY: problem`` when the file cannot be read or its ``[network]`` is bad."""
    if rig_config is None:
        return None
    from analysis.table.configuration import read_configuration
    from analysis.table.limits import TableModelError

    try:
        return read_configuration(rig_config).network
    except TableModelError as exc:
        fail(str(exc))
