"""``rig table list --connect ENDPOINT``: what is on the zenoh network — the table controllers and rig services that
declare liveliness tokens (``shaketable/<name>/alive/<role>``), each with its identity (name and role), the
transport it was found over and its state (a table's from its STATUS, verified with the rig's key when one is
given; a service's from its telemetry).

The ``table`` command group is shared: :func:`add_list` adds ``list`` to whichever group holds the other ``rig table``
commands.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from rig.cli._common import console, emit_json, fail
from rig.cli.network import Insecure, TlsCa, TlsCert, TlsKey, link_security
from rig.cli.passphrase import KeyPassphrase, use_key_passphrase

LISTEN_S = 1.5
"""How long ``rig table list`` waits for the tokens and each one's state [s]."""


def add_list(table_app: typer.Typer) -> None:
    """Add ``list`` to the ``rig table`` group ``table_app``."""

    @table_app.command("list")
    def list_cmd(
        connect: Annotated[list[str], typer.Option(help="a zenoh endpoint to look through (repeat), e.g. "
                                                       "tls/10.231.0.2:7447")],
        key_file: Annotated[Path | None, typer.Option(help="the rig's key: verify the tables' statuses")] = None,
        tls_ca: TlsCa = None, tls_cert: TlsCert = None, tls_key: TlsKey = None, insecure_plain_tcp: Insecure = False,
        as_json: Annotated[bool, typer.Option("--json", help="print the list as JSON")] = False,
        key_passphrase: KeyPassphrase = None,
    ) -> None:
        """List the table controllers and rig services reachable through the endpoints (their liveliness tokens)."""
        from protocols.signing_key import SigningKeyError
        from protocols.zenoh import EndpointError

        use_key_passphrase(key_passphrase, key_file)
        security = link_security(tls_ca, tls_cert, tls_key, insecure_plain_tcp)
        try:
            found = discover(connect, security, key_file, verify=key_file is not None or key_passphrase is not None)
        except (EndpointError, SigningKeyError) as exc:
            fail(str(exc))
        if as_json:
            emit_json({"found": found})
            return
        from rich.table import Table

        table = Table(title="on the network")
        for column in ("name", "role", "transport", "state"):
            table.add_column(column)
        for item in found:
            table.add_row(item["name"], item["role"], item["transport"], item["state"])
        console.print(table)


def discover(connect: list[str], security: Any, key_file: Path | None, verify: bool) -> list[dict[str, str]]:
    """The liveliness tokens seen through ``connect`` and each one's state (module docstring), sorted by name; with
    ``verify`` the tables' statuses are verified with the rig's key (``key_file``, else ``$SHAKETABLE_MAVLINK_KEY``,
    where ``--key-passphrase`` puts it)."""
    import functools
    import threading

    import zenoh

    from protocols.signing_key import load_signing_key
    from protocols.zenoh import alive_selector, parse_key, session_config, table_key, telemetry_key
    from protocols.zenoh.auth import Verdict, Verifier, split_signed
    from protocols.zenoh.payloads import Kind, PayloadError, decode_json
    from protocols.zenoh.table import decode_status

    verifier = Verifier(load_signing_key(key_file)) if verify else None
    transport = f"zenoh {'mutual TLS' if security.tls is not None else 'plain tcp'} via {', '.join(connect)}"
    session = zenoh.open(session_config(connect=connect, security=security))
    try:
        found: dict[tuple[str, str], dict[str, str]] = {}
        deadline = threading.Event()
        for attempt in range(3):  # the link is made in the background: the first query may find no route yet
            for reply in session.liveliness().get(alive_selector(), timeout=LISTEN_S / 3):
                if reply.ok is None:
                    continue
                key = parse_key(str(reply.ok.key_expr))
                found[(key.rig, key.name)] = {"name": key.rig, "role": key.name, "transport": transport,
                                              "state": "unknown"}
            if found:
                break
            deadline.wait(0.1 * (attempt + 1))
        lock = threading.Lock()

        def on_table(name: str, sample: zenoh.Sample) -> None:
            received = split_signed(sample.payload.to_bytes())
            try:
                status = decode_status(received.message)
            except PayloadError:
                return
            with lock:
                verdict = verifier.verify(str(sample.key_expr), received) if verifier is not None else None
                mark = ("" if verdict is Verdict.SIGNED else " (unverified: no --key-file or --key-passphrase)"
                        if verdict is None else " (signature does not verify with the rig's key)")
                found[(name, "table")]["state"] = status.state + mark

        def on_service(name: str, sample: zenoh.Sample) -> None:
            try:
                found[(name, "service")]["state"] = str(decode_json(sample.payload.to_bytes(), Kind.STATUS)["state"])
            except (PayloadError, KeyError):
                return

        subscribers = []
        for name, role in list(found):
            if role == "table":
                subscribers.append(session.declare_subscriber(table_key(name, "status"),
                                                              functools.partial(on_table, name)))
            elif role == "service":
                subscribers.append(session.declare_subscriber(telemetry_key(name, "status"),
                                                              functools.partial(on_service, name)))
        deadline.wait(LISTEN_S if subscribers else 0.0)
        for subscriber in subscribers:
            subscriber.undeclare()
        with lock:
            return [found[k] for k in sorted(found)]
    finally:
        session.close()
