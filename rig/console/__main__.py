"""``python -m rig.console --connect ENDPOINT --http HOST:PORT [--key-file FILE] [--rig NAME] [--exit-with-parent]
[--http-name NAME]… [--tokens FILE] [--https-cert FILE --https-key FILE | --https-dir DIR]``:
the console as its own process (what ``rig console``, ``rig serve --http`` and ``rig run --console`` run)."""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

from protocols.zenoh import LinkSecurity
from protocols.zenoh.tls import TlsError, load_tls
from rig.console.server import ConsoleError, WebAccess, serve_console

PARENT_POLL_S = 0.2
"""How often ``--exit-with-parent`` looks whether the process that started the console is still there [s]."""


def end_with_parent(say: Callable[[str], None]) -> None:
    """SIGTERM this process (the console's clean shutdown) once the process that started it has exited — this one
    re-parented — looked at every :data:`PARENT_POLL_S`: a console started by ``rig`` never outlives it, even after
    ``kill -9`` of ``rig``, so no orphan keeps its HTTP port."""
    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        with contextlib.suppress(OSError):  # its stderr pipe may have gone with it
            say(f"the process {parent} that started the console exited: stopping")
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rig.console", description=__doc__)
    parser.add_argument("--connect", required=True, help="the rig service's zenoh endpoint")
    parser.add_argument("--http", required=True, help="HOST:PORT to serve the page on (off loopback: HTTPS)")
    parser.add_argument("--http-name", action="append", default=[], help="a name browsers reach the console at")
    parser.add_argument("--tokens", type=Path, help="the tokens file of operators and viewers (re-read on change)")
    parser.add_argument("--https-cert", type=Path, help="the console's HTTPS certificate (PEM)")
    parser.add_argument("--https-key", type=Path, help="the private key of --https-cert (PEM)")
    parser.add_argument("--https-dir", type=Path, help="serve HTTPS with DIR/console.pem, made on first use")
    parser.add_argument("--key-file", type=Path, default=None, help="the rig's key (default $SHAKETABLE_MAVLINK_KEY)")
    parser.add_argument("--rig", default="rig", help="the rig's name in the key space")
    parser.add_argument("--tls-ca", type=Path, help="the lab's CA certificate (zenoh link to the service over TLS)")
    parser.add_argument("--tls-cert", type=Path, help="this console's certificate, signed by the lab's CA")
    parser.add_argument("--tls-key", type=Path, help="the private key of --tls-cert")
    parser.add_argument("--insecure-plain-tcp", action="store_true", help="allow a plain tcp/ link off loopback")
    parser.add_argument("--exit-with-parent", action="store_true",
                        help="stop when the process that started the console exits (how rig starts it)")
    args = parser.parse_args(argv)

    def say(message: str) -> None:
        print(f"rig console: {message}", file=sys.stderr, flush=True)

    if args.exit_with_parent:
        end_with_parent(say)
    try:
        security = LinkSecurity(load_tls(args.tls_ca, args.tls_cert, args.tls_key), args.insecure_plain_tcp)
    except TlsError as exc:
        say(f"error: {exc}")
        return 2
    try:
        access = WebAccess(tuple(args.http_name), args.tokens, args.https_cert, args.https_key, args.https_dir)
        serve_console(args.connect, args.http, key_file=args.key_file, rig=args.rig, say=say, security=security,
                      access=access)
    except ConsoleError as exc:
        say(f"error: {exc}")
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
