"""Running the console: :func:`serve_console` (``rig console``) serves the page with uvicorn in this process,
subscribed to the rig service's telemetry, its controls sent to the service as a zenoh client.

The console is its own process (``rig serve --http`` and ``rig run --console`` start it with
:class:`ConsoleProcess`): its interpreter, event loop and browsers never share a lock with the orchestrator or the
session writer; what connects them is the service's zenoh telemetry and control plane on loopback.
"""

from __future__ import annotations

import ipaddress
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

from protocols.signing_key import SigningKeyError
from protocols.zenoh import LinkSecurity
from protocols.zenoh.config import PLAIN
from rig.console.access import AccessError, TokensFile
from rig.console.app import Console, create_app
from rig.console.feed import TelemetrySubscription
from rig.console.guard import ConnectionGuard, guarded_protocol
from rig.console.https import HttpsError, HttpsFiles, https_files
from rig.console.token import token_from_key_file
from rig.service import DEFAULT_RIG, ServiceClient

READY = "console at "
"""What the console prints on stderr once it serves (followed by its URL)."""

START_WAIT = 60.0
"""How long :class:`ConsoleProcess` waits for the console to serve [s]."""


class ConsoleError(Exception):
    """The console could not start (bad address, no service, the port taken)."""


def parse_http(address: str) -> tuple[str, int]:
    """``HOST:PORT`` (``127.0.0.1:8080``, ``[::1]:8080``) as (host, port); :class:`ConsoleError` when malformed."""
    host, sep, port = address.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) < 65536:
        raise ConsoleError(f"--http {address!r}: expected HOST:PORT, e.g. 127.0.0.1:8080")
    return host, int(port)


class WebAccess(NamedTuple):
    """How the console is reached and who may use it: ``names`` the DNS names (or further addresses) browsers
    reach it at (``--http-name``: the Host/Origin checks accept them), ``tokens`` the tokens file of operators and
    viewers (:mod:`rig.console.access`), the HTTPS certificate given (``https_cert``, ``https_key``) or made on first
    use in ``https_dir`` (:mod:`rig.console.https`)."""

    names: tuple[str, ...] = ()
    tokens: Path | None = None
    https_cert: Path | None = None
    https_key: Path | None = None
    https_dir: Path | None = None

    def arguments(self) -> list[str]:
        """The same as ``python -m rig.console`` options."""
        words = [word for name in self.names for word in ("--http-name", name)]
        for option, value in (("--tokens", self.tokens), ("--https-cert", self.https_cert),
                              ("--https-key", self.https_key), ("--https-dir", self.https_dir)):
            if value is not None:
                words += [option, str(value)]
        return words


LOOPBACK_ONLY = WebAccess()
"""No other names, no tokens file, plain HTTP (on loopback only)."""


def allowed_hosts(host: str, port: int, names: tuple[str, ...] = ()) -> set[str]:
    """The ``Host`` headers the console answers controls from: its address, the ``names`` it was told it is reached
    at, and localhost's names when it listens on loopback (a page reached through any other name — DNS
    rebinding — is refused); on port 80 or 443 also without the port."""
    hosts = {host, f"[{host}]" if ":" in host else host, *(f"[{n}]" if ":" in n else n for n in names)}
    try:
        if ipaddress.ip_address(host).is_loopback:
            hosts |= {"localhost", "127.0.0.1", "[::1]"}
    except ValueError:
        pass
    # a browser leaves the scheme's default port out of Host
    return {f"{name}:{port}" for name in hosts} | (hosts if port in (80, 443) else set())


class ServiceControls:
    """The page's controls sent to the rig service (``ServiceClient``; resume signed with the rig's key); one
    command at a time."""

    def __init__(self, client: ServiceClient) -> None:
        self.client = client
        self._lock = threading.Lock()

    def command(self, command: str, source: str, args: dict[str, Any]) -> dict[str, Any]:
        with self._lock:
            if command == "start":
                queued = args.get("queued")  # the browser's, passed on: the service checks it
                session = self.client.start_queued(queued)  # type: ignore[arg-type]  # as the browser sent it
                return {"ok": True, "message": f"session started: {session}", "state": "starting"}
            if command == "answer":
                return self.client.answer(args.get("prompt"),  # type: ignore[arg-type]  # the service checks it
                                          args.get("reply"),  # type: ignore[arg-type]  # as prompt
                                          args.get("fell"), source=source)
            method = {"pause": self.client.pause, "resume": self.client.resume, "abort": self.client.abort,
                      "estop": self.client.emergency_stop}[command]
            return method(source=source)

    def refused(self, command: str, source: str, reason: str) -> None:
        with self._lock:
            self.client.refused(command, source, reason)


def console_server(console: Console, host: str, port: int, *, say: Callable[[str], None] = lambda message: None,
                   on_startup: Callable[[Any], None] | None = None, on_shutdown: Callable[[], None] | None = None,
                   guard: ConnectionGuard | None = None, https: HttpsFiles | None = None) -> Any:
    """The uvicorn server of ``console`` at ``host``:``port`` (not yet running: ``.run()``), its connections bounded
    by ``guard`` (:mod:`rig.console.guard`; default: its defaults, logging to ``say``), over TLS with ``https``."""
    import uvicorn

    guard = guard or ConnectionGuard(say)
    console.connection_stats = guard.stats
    app = create_app(console, on_startup=on_startup, on_shutdown=on_shutdown)
    return uvicorn.Server(uvicorn.Config(app, host=host, port=port, log_level="warning", lifespan="on",
                                         loop="asyncio", http=guarded_protocol(guard), timeout_keep_alive=5,
                                         ssl_certfile=None if https is None else str(https.certificate),
                                         ssl_keyfile=None if https is None else str(https.key)))


def serve_console(connect: str, http: str, *, key_file: Path | None = None, rig: str = DEFAULT_RIG,
                  say: Callable[[str], None] = lambda message: None, security: LinkSecurity = PLAIN,
                  access: WebAccess = LOOPBACK_ONLY) -> None:
    """Serve the console at ``http`` (``HOST:PORT``) for the rig service at ``connect`` until SIGINT/SIGTERM.
    Without the rig's key (``key_file``, else ``$SHAKETABLE_MAVLINK_KEY``) the page is read-only (unless the tokens
    file names operators). ``security``: the zenoh link to the service (its TLS identity); ``access``: the names,
    tokens and HTTPS certificate (:class:`WebAccess`)."""
    host, port = parse_http(http)
    try:
        https = https_files(host, access.names, certificate=access.https_cert, key=access.https_key,
                            directory=access.https_dir, say=say)
        tokens = TokensFile(access.tokens, say) if access.tokens is not None else None
    except (HttpsError, AccessError) as exc:
        raise ConsoleError(str(exc)) from None
    try:
        token: str | None = token_from_key_file(key_file)
    except SigningKeyError as exc:
        token = None
        say(f"read-only: no operator token ({exc})")
    from rig.service import ServiceError

    try:
        client = ServiceClient(connect, key_file if token else None, security=security)
    except ServiceError as exc:
        raise ConsoleError(str(exc)) from None
    console = Console(ServiceControls(client), token, allowed_hosts=allowed_hosts(host, port, access.names),
                      tokens=tokens, say=say)
    subscription: list[TelemetrySubscription] = []

    def startup(loop: Any) -> None:
        subscription.append(TelemetrySubscription(connect, console.deliver_from(loop), rig, security))

    def shutdown() -> None:
        for sub in subscription:
            sub.close()

    server = console_server(console, host, port, say=say, on_startup=startup, on_shutdown=shutdown, https=https)
    announce = threading.Thread(target=_announce, args=(server, say, "https" if https else "http"), daemon=True)
    announce.start()
    try:
        server.run()
    finally:
        client.close()
    if not server.started:
        raise ConsoleError(f"the console could not listen on {http} (port in use?)")


def _announce(server: Any, say: Callable[[str], None], scheme: str) -> None:
    while not server.started and not server.should_exit:
        time.sleep(0.05)
    if server.started:
        for sock in (s for srv in server.servers for s in srv.sockets):
            host, port = sock.getsockname()[:2]
            say(f"{READY}{scheme}://{f'[{host}]' if ':' in host else host}:{port}/")
            return


class ConsoleProcess:
    """``python -m rig.console`` as a child process (``rig serve --http``, ``rig run --console``) in a session of its
    own (the terminal's Ctrl-C is the parent's to handle), ending when this process ends (``--exit-with-parent``,
    also after ``kill -9``): started and waited for until it serves; its stderr forwarded to ``say``; :meth:`stop`
    ends it (SIGTERM)."""

    def __init__(self, connect: str, http: str, *, key_file: Path | None = None, rig: str = DEFAULT_RIG,
                 say: Callable[[str], None] = lambda message: None, security: LinkSecurity = PLAIN,
                 access: WebAccess = LOOPBACK_ONLY) -> None:
        parse_http(http)
        command = [sys.executable, "-m", "rig.console", "--connect", connect, "--http", http, "--rig", rig,
                   "--exit-with-parent", *access.arguments()]
        if key_file is not None:
            command += ["--key-file", str(key_file)]
        if security.tls is not None:
            command += ["--tls-ca", str(security.tls.ca), "--tls-cert", str(security.tls.certificate),
                        "--tls-key", str(security.tls.key)]
        if security.insecure:
            command += ["--insecure-plain-tcp"]
        self.url: str | None = None
        self._say = say
        self._ready = threading.Event()
        # a session of its own: the terminal's Ctrl-C (which pauses the run) does not reach the console
        self.proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                     env=os.environ.copy(), start_new_session=True)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        deadline = time.monotonic() + START_WAIT
        while not self._ready.wait(0.1):
            if self.proc.poll() is not None or time.monotonic() > deadline:
                self.stop()
                raise ConsoleError(f"the console did not start (exit code {self.proc.returncode})")

    def _read(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            line = line.rstrip("\n")
            if line.startswith(f"rig console: {READY}"):
                self.url = line.removeprefix(f"rig console: {READY}")
                self._ready.set()
            self._say(line)

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._reader.join(2)

    def __enter__(self) -> ConsoleProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
