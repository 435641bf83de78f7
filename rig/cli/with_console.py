"""``rig run … --console HOST:PORT``: a run without a separate ``rig serve``, watched and controlled from the console.

The console only ever talks to the rig service (its zenoh telemetry and control plane), so that the page sees and
commands exactly what ``rig serve --http`` shows. For a plain ``rig run`` this process therefore starts a rig
service of its own on a free loopback zenoh port (in this process: the orchestrator runs in the service's worker
thread), the console as a child process subscribed to it, and follows the session as ``rig run --service`` does (the
status line, Ctrl-C pauses then aborts). Like every service session it runs unattended: the bodies are taken as
placed (confirmed once at the start unless ``--yes``). Without a key (``--key-file`` or ``$SHAKETABLE_MAVLINK_KEY``)
a one-session key is made, and the operator token printed here. With ``--service ENDPOINT`` too, only the console
is started here, for that service.

When the session ends the console **stays up** — the page keeps showing the final state, the faults and the link
to the report, and its controls can start a session queued on the service (``rig service queue``) — until the
operator presses Ctrl-C, or ``--console-linger SECONDS`` after the end (0: at once). The exit code is the session's.
"""

from __future__ import annotations

import math
import os
import socket
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from protocols.signing_key import write_signing_key
from rig.cli._common import EXIT_USAGE, handle_sigint, print_error

if TYPE_CHECKING:  # imported where used (rig --help loads no web server)
    from protocols.zenoh import LinkSecurity
    from rig.console import WebAccess


def _free_endpoint() -> str:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{probe.getsockname()[1]}"


def linger(url: str | None, seconds: float | None, console: Any) -> None:
    """Keep the console up after the session: until Ctrl-C (SIGINT, handled here whatever this process inherited:
    started in the background of a script, SIGINT comes ignored and Python raises no KeyboardInterrupt), or
    ``seconds`` (None: no limit)."""
    limit = math.inf if seconds is None else seconds
    if limit <= 0:
        return
    until = "Ctrl-C closes it" if seconds is None else f"it closes in {seconds:g} s (Ctrl-C: now)"
    console.print(f"the console stays up at {url} with the final state, the faults and the report; {until}",
                  highlight=False)
    interrupted: list[int] = []
    previous = handle_sigint(lambda signum, frame: interrupted.append(signum))
    try:
        deadline = time.monotonic() + limit
        while not interrupted and time.monotonic() < deadline:
            time.sleep(min(0.2, max(0.0, deadline - time.monotonic())))
    finally:
        handle_sigint(previous)
    console.print("console closed", highlight=False)


def run_with_console(http: str, sequence: Path | None, *, table: str | None, emulate: bool, output: Path | None,
                     resume: Path | None, yes: bool, console: Any, key_file: Path | None, speed: float,
                     service: str | None = None, linger_s: float | None = None, security: LinkSecurity | None = None,
                     access: WebAccess | None = None) -> int:
    """Play the session through an in-process rig service (or the one at ``service``) with the console at ``http``,
    which stays up after it for ``linger_s`` s (None: until Ctrl-C) (module docstring); the exit code of ``rig run
    --service`` (0 all runs done, 1 stopped early, 2 refused). ``access``: the console's names, tokens file and HTTPS
    certificate (``rig serve --http``'s options; None: loopback, plain HTTP); ``security``: the zenoh link's TLS
    identity to the service at ``service``, or (the in-process service listens on loopback) to a zenoh table."""
    from protocols.signing_key import KEY_ENV
    from rig.cli.serve import drive_service
    from rig.console.server import ConsoleError, ConsoleProcess
    from rig.console.token import token_from_key_file
    from rig.service import OrchestratorService, ServiceError

    def say(message: str) -> None:
        console.print(f"[dim]{message}[/]", highlight=False)

    web: dict[str, Any] = {} if access is None else {"access": access}
    link: dict[str, Any] = {} if security is None else {"security": security}

    if service is not None:  # a rig serve elsewhere: only the console is started here
        try:
            page = ConsoleProcess(service, http, key_file=key_file, say=say, **link, **web)
        except ConsoleError as exc:
            print_error(console, "error", str(exc))
            return EXIT_USAGE
        with page:
            console.print(f"operator console: {page.url}", highlight=False)
            code = drive_service(service, sequence, table=table, emulate=emulate, output=output, resume=resume,
                                 yes=yes, console=console, key_file=key_file, speed=speed, security=security)
            linger(page.url, linger_s, console)
            return code

    again = f"--console {http}" + (f" --key-file {key_file}" if key_file is not None else "")
    with tempfile.TemporaryDirectory(prefix="rig-console-") as scratch:
        if key_file is None and not os.environ.get(KEY_ENV):
            key_file = Path(scratch) / "session.key"
            write_signing_key(key_file)
        endpoint = _free_endpoint()
        try:
            own_service = OrchestratorService(endpoint, key_file=key_file, sessions_dir=Path.cwd(),
                                              say=lambda m: say(f"rig service: {m}"), table_security=security)
        except ServiceError as exc:
            print_error(console, "error", str(exc))
            return EXIT_USAGE
        try:
            try:
                page = ConsoleProcess(endpoint, http, key_file=key_file, say=say, **web)
            except ConsoleError as exc:
                print_error(console, "error", str(exc))
                return EXIT_USAGE
            with page:
                console.print(f"operator console: {page.url} (operator token {token_from_key_file(key_file)})",
                              highlight=False)
                # this service ends with this command (its console lingers): a new one continues the session
                code = drive_service(endpoint, sequence, table=table, emulate=emulate, output=output, resume=resume,
                                     yes=yes, console=console, key_file=key_file, speed=speed, resume_with=again)
                linger(page.url, linger_s, console)
                return code
        finally:
            own_service.close()
