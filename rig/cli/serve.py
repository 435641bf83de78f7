"""``rig serve`` (the orchestrator as a service, zenoh control plane), ``rig service …`` (its one-shot commands) and
:func:`drive_service` (what ``rig run --service`` runs: start a sequence on the service and follow it).

``rig serve --listen tcp/127.0.0.1:7447`` runs until SIGINT or SIGTERM; then a running session is aborted (a
controlled stop, the run logged ``aborted``, the file resumable) and the service waits for the table to come to rest.
A second signal makes that an emergency stop. ``start``/``resume`` must be signed with the rig's key (``--key-file``
or ``$SHAKETABLE_MAVLINK_KEY``) unless ``--no-auth``; pause, abort and emergency stop are open to any client
(``rig.service.server``).
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.live import Live
from rich.prompt import Confirm
from rich.text import Text

from rig.cli._common import EXIT_STOPPED, EXIT_USAGE, console, emit_json, fail, handle_sigint, print_error
from rig.cli.network import (
    Insecure,
    NetworkConfig,
    TlsCa,
    TlsCert,
    TlsKey,
    configured_security,
    link_security,
    network_of,
)
from rig.cli.passphrase import KeyPassphrase, use_key_passphrase
from rig.cli.web import HttpName, HttpsCert, HttpsDir, HttpsKey, TokensOption, web_access

if TYPE_CHECKING:  # imported where used (ISSUE 16: `rig --help` must not load zenoh, h5py, …)
    from protocols.zenoh import LinkSecurity
    from rig.service import ServiceClient, TelemetryFeed

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
"""Where ``rig serve`` listens and the clients connect by default."""

ConnectOption = Annotated[str, typer.Option("--connect", help="the rig service's zenoh endpoint")]
KeyOption = Annotated[Path | None, typer.Option(help="the rig's key file (default: $SHAKETABLE_MAVLINK_KEY)")]



# ----- rig run --service -------------------------------------------------------------------------------------


def drive_service(connect: str, sequence: Path | None, *, table: str | None, emulate: bool, output: Path | None,
                  resume: Path | None, yes: bool, console: Any, key_file: Path | None = None,
                  speed: float = 1.0, resume_with: str | None = None, security: LinkSecurity | None = None) -> int:
    """Start ``sequence`` (or ``resume`` a session file) on the rig service at ``connect`` and follow it.

    The status line shows the service's telemetry. Ctrl-C sends pause (the session pauses at the end of the current
    record; then: resume, or end the session there — with ``yes`` it ends there), a second Ctrl-C sends abort.
    Without ``yes`` the operator confirms the start first (the service runs sequences unattended). A session that
    stopped early names the command that continues it: ``rig run RESUME_WITH --resume SESSION`` (default
    ``--service CONNECT``: this service again). ``security``: the zenoh link's TLS identity. Returns the exit code:
    0 all runs done, 1 the session stopped early
    (or was not started), 2 the service refused or is absent.
    """
    from rig.service import ServiceClient, ServiceError

    try:
        link: dict[str, Any] = {} if security is None else {"security": security}
        client = ServiceClient(connect, key_file, **link)
    except ServiceError as exc:
        print_error(console, "error", str(exc))
        return EXIT_USAGE
    with client, client.telemetry() as feed:
        what = f"resume {resume}" if resume is not None else f"run {sequence}"
        if not yes and not _confirm(f"{what.capitalize()} on the rig service at {connect}? It runs unattended: "
                                    "the bodies are taken as placed and every run starts at once.", console):
            console.print("not started")
            return EXIT_STOPPED
        interrupts = [0]  # Ctrl-C while the service prepares the session: acted on once it runs

        def on_sigint(signum: int, frame: object) -> None:
            interrupts[0] += 1

        previous = handle_sigint(on_sigint)
        try:
            try:
                session = client.start(sequence, table=table, emulate=emulate, speed=speed, output=output,
                                       resume=resume)
                seq = client.state()["seq"]
            except ServiceError as exc:
                print_error(console, "error", str(exc))
                return EXIT_USAGE
            console.print(f"session file: {session}", highlight=False)
            final = _follow(client, feed, session, seq, interrupts, yes, console)
        finally:
            handle_sigint(previous)
    if final is None:
        return EXIT_STOPPED
    progress = final["progress"]
    console.print(f"[bold]{final['state']}[/]: {final['message']}", highlight=False)
    if final["state"] == "done" and progress["runs_done"] == progress["runs_total"]:
        return 0
    again = f"--service {connect}" if resume_with is None else resume_with
    key = f" --key-file {key_file}" if key_file is not None and resume_with is None else ""
    console.print(f"{progress['runs_done']} of {progress['runs_total']} runs done; continue the session with "
                  f"rig run {again} --resume {session}{key}", highlight=False, soft_wrap=True)
    return EXIT_STOPPED


class _Display:
    """The status line: redrawn in place on a terminal, else printed when the state or the runs done change."""

    def __init__(self, console: Any) -> None:
        self.console = console
        self.live = Live(Text("waiting for the service's telemetry"), console=console, transient=False,
                         refresh_per_second=8) if console.is_terminal else None
        self._last: tuple[Any, ...] | None = None

    def __enter__(self) -> _Display:
        if self.live is not None:
            self.live.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.hold()

    def update(self, status: dict[str, Any]) -> None:
        if self.live is not None:
            self.live.update(status_line(status))
            return
        key = (status["state"], status["progress"]["runs_done"])
        if key != self._last:
            self._last = key
            self.console.print(status_line(status))

    def print(self, message: str) -> None:
        self.console.print(message, highlight=False)

    def hold(self) -> None:
        """Stop redrawing (a prompt follows)."""
        if self.live is not None:
            self.live.stop()

    def go_on(self) -> None:
        if self.live is not None:
            self.live.start()


def _follow(client: ServiceClient, feed: TelemetryFeed, session: str, seq: int, interrupts: list[int], yes: bool,
            console: Any) -> dict[str, Any] | None:
    """Show the session's telemetry until its final state (returned; None if the service went away);
    ``interrupts[0]`` counts the Ctrl-C (the caller's SIGINT handler)."""
    from rig.orchestrator import FINAL_STATES
    from rig.service import ServiceUnavailableError
    from rig.service.client import SILENCE

    final_states = {state.value for state in FINAL_STATES}  # the states that end a session's invocation
    sent = 0
    ours_paused = False
    silent = 0.0
    try:
        with _Display(console) as display:
            while True:
                if interrupts[0] > sent:
                    sent = interrupts[0]
                    ours_paused = _interrupt(client, sent, display) or ours_paused
                status = feed.get(0.1)
                if status is None:
                    silent += 0.1
                    if silent <= SILENCE:
                        continue
                    status = client.state()  # ServiceUnavailableError when the service is gone
                silent = 0.0
                if status["session"] != session or status["seq"] < seq:
                    continue
                display.update(status)
                if status["state"] in final_states:
                    return status
                if status["state"] == "paused" and ours_paused:
                    ours_paused = False
                    display.hold()
                    if _after_pause(client, yes, console):
                        interrupts[0] = sent = 0
                    display.go_on()
    except ServiceUnavailableError as exc:
        print_error(console, "error", str(exc))
        return None


def _interrupt(client: ServiceClient, count: int, display: _Display) -> bool:
    """Ctrl-C number ``count``: pause (True), then abort."""
    from rig.service import ServiceError

    try:
        if count == 1:
            client.pause()
            display.print("pause requested: the session pauses at the end of the current record "
                          "(Ctrl-C again: abort)")
            return True
        client.abort()
        display.print("abort requested: the table stops and returns home")
    except ServiceError as exc:
        display.print(f"error: {exc}")
    return False


def _after_pause(client: ServiceClient, yes: bool, console: Any) -> bool:
    """Paused at the end of a record on our Ctrl-C: resume (True), or end the session there (resumable)."""
    from rig.service import ServiceError

    go_on = not yes and _confirm("Paused at the end of the record. Resume?", console)
    try:
        if go_on:
            client.resume()
            return True
        console.print("the session ends here (resumable: the command is printed below)")
        client.abort()
    except ServiceError as exc:
        print_error(console, "error", str(exc))
    return False


def _confirm(question: str, console: Any) -> bool:
    try:
        return Confirm.ask(question, default=True, console=console)
    except (EOFError, KeyboardInterrupt):
        return False


def status_line(status: dict[str, Any]) -> Text:
    """One line of the service's status: state, runs, the run's samples, table, peak acceleration, message."""
    p = status["progress"]
    run = p["run"]
    label = f"run {run['plan_index'] + 1}" if isinstance(run, dict) and "plan_index" in run else "run -"
    peak = p["peak_accel"] or 0.0
    return Text.assemble(
        ("state ", "dim"), (status["state"], "bold"), ("  runs ", "dim"), (f"{p['runs_done']}/{p['runs_total']}", ""),
        ("  ", ""), (label, "dim"), (f" {p['samples_sent']}/{p['samples_total']}", ""),
        ("  table ", "dim"), (p["table_state"] or "-", ""), ("  peak ", "dim"), (f"{peak / 9.81:.3f} g", ""),
        ("  overturns ", "dim"), (f"{p['detections']}", ""), ("  ", ""), (status["message"], "italic"))


# ----- rig serve and rig service -----------------------------------------------------------------------------


def serve(listen: str, sessions_dir: Path, key_file: Path | None, no_auth: bool, fail: Callable[[str], Any],
          http: str | None = None, security: LinkSecurity | None = None, access: Any = None) -> None:
    """Run the service until SIGINT/SIGTERM (module docstring); with ``http`` (``HOST:PORT``) the operator's
    console (``rig.console``) too, as a child process subscribed to the service's telemetry; ``security`` the zenoh
    session's TLS identity (the console uses it too); ``access`` the console's ``rig.console.WebAccess``."""
    from rig.service import OrchestratorService, ServiceError

    def say(message: str) -> None:
        print(f"rig serve: {message}", file=sys.stderr, flush=True)

    try:
        link: dict[str, Any] = {} if security is None else {"security": security}
        service = OrchestratorService(listen, key_file=key_file, sessions_dir=sessions_dir,
                                      require_auth=not no_auth, say=say, **link)
    except ServiceError as exc:
        fail(str(exc))
    signals = [0]
    stop = threading.Event()

    def on_signal(signum: int, frame: object) -> None:
        signals[0] += 1
        stop.set()
        if signals[0] >= 2:
            threading.Thread(target=service.stop_session, args=("emergency stop",), daemon=True).start()

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    console = None
    try:
        if http is not None:
            from rig.console import ConsoleError, ConsoleProcess

            try:
                web = {} if access is None else {"access": access}
                console = ConsoleProcess(listen, http, key_file=key_file, say=lambda line: print(line, file=sys.stderr,
                                                                                                 flush=True), **link,
                                         **web)
            except ConsoleError as exc:
                service.close()
                fail(str(exc))
        auth = "start/resume must be signed" if service.authenticated else "start/resume NOT authenticated"
        encrypted = ("mutual TLS" if listen.startswith("tls/") else
                     "PLAIN TEXT (--insecure-plain-tcp)" if security is not None and security.insecure else "loopback")
        say(f"listening on {listen} ({encrypted}; sessions in {service.sessions_dir}; {auth})")
        while not stop.wait(0.5):
            pass
        say("stopping")
        if console is not None:
            console.stop()
        service.close()
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
    say("stopped")


def _parse_speed(text: str | float) -> float:
    """``--speed`` (``rig.emulator.parse_speed``, imported when the option is given)."""
    from rig.emulator import parse_speed

    return parse_speed(text)


def register(app: typer.Typer) -> None:
    """Add ``rig serve`` and the ``rig service`` commands to the ``rig`` application."""

    @app.command("serve")
    def serve_cmd(
        listen: Annotated[str, typer.Option(help="zenoh endpoint to listen on: tcp/ on loopback, tls/ADDRESS:PORT "
                                                 "across hosts (with --tls-*)")] = DEFAULT_ENDPOINT,
        sessions_dir: Annotated[Path, typer.Option(help="where the session files go")] = Path("."),
        key_file: KeyOption = None,
        no_auth: Annotated[bool, typer.Option("--no-auth", help="accept unsigned start/resume (a bench without a "
                                                                "table)")] = False,
        http: Annotated[str | None, typer.Option(help="also serve the operator's console (a web page) at HOST:PORT, "
                                                      "e.g. 127.0.0.1:8080")] = None,
        tls_ca: TlsCa = None, tls_cert: TlsCert = None, tls_key: TlsKey = None, insecure_plain_tcp: Insecure = False,
        http_name: HttpName = None, tokens: TokensOption = None, https_cert: HttpsCert = None,
        https_key: HttpsKey = None, https_dir: HttpsDir = None, key_passphrase: KeyPassphrase = None,
        rig_config: NetworkConfig = None,
    ) -> None:
        """Run the orchestrator as a service controlled over zenoh, until Ctrl-C or SIGTERM."""
        use_key_passphrase(key_passphrase, key_file)
        network = network_of(rig_config)
        security = link_security(tls_ca, tls_cert, tls_key, insecure_plain_tcp)
        if network is not None and listen.lower().startswith("tls/"):  # a tls/ endpoint needs an identity
            security = configured_security(security, network)
        serve(listen, sessions_dir, key_file, no_auth, fail, http, security,
              web_access(http_name, tokens, https_cert, https_key, https_dir,
                         None if network is None else network.console))

    @app.command("console")
    def console_cmd(
        http: Annotated[str, typer.Option(help="HOST:PORT to serve the page on")] = "127.0.0.1:8080",
        connect: ConnectOption = DEFAULT_ENDPOINT, key_file: KeyOption = None,
        tls_ca: TlsCa = None, tls_cert: TlsCert = None, tls_key: TlsKey = None, insecure_plain_tcp: Insecure = False,
        http_name: HttpName = None, tokens: TokensOption = None, https_cert: HttpsCert = None,
        https_key: HttpsKey = None, https_dir: HttpsDir = None, key_passphrase: KeyPassphrase = None,
        rig_config: NetworkConfig = None,
    ) -> None:
        """Serve the operator's console (live web page and controls) for a running `rig serve`."""
        from rig.console import ConsoleError, serve_console

        use_key_passphrase(key_passphrase, key_file)
        network = network_of(rig_config)
        security = link_security(tls_ca, tls_cert, tls_key, insecure_plain_tcp)
        if network is not None and connect.lower().startswith("tls/"):
            security = configured_security(security, network)
        access = web_access(http_name, tokens, https_cert, https_key, https_dir,
                            None if network is None else network.console)
        try:
            serve_console(connect, http, key_file=key_file, security=security, access=access,
                          say=lambda message: print(f"rig console: {message}", file=sys.stderr, flush=True))
        except ConsoleError as exc:
            fail(str(exc))

    service_app = typer.Typer(help="Commands to a running `rig serve`.", no_args_is_help=True)

    def command(name: str, method: str, help_text: str) -> None:
        @service_app.command(name, help=help_text)
        def run_command(connect: ConnectOption = DEFAULT_ENDPOINT, key_file: KeyOption = None,
                        as_json: Annotated[bool, typer.Option("--json", help="print the reply as JSON")] = False,
                        tls_ca: TlsCa = None, tls_cert: TlsCert = None, tls_key: TlsKey = None,
                        insecure_plain_tcp: Insecure = False, key_passphrase: KeyPassphrase = None) -> None:
            from rig.service import ServiceClient, ServiceError

            use_key_passphrase(key_passphrase, key_file)
            security = link_security(tls_ca, tls_cert, tls_key, insecure_plain_tcp)
            try:
                with ServiceClient(connect, key_file, security=security) as client:
                    reply = getattr(client, method)()
            except ServiceError as exc:
                fail(str(exc))
            if as_json:
                emit_json(reply)
            elif name == "state":
                console.print(status_line(reply))
                console.print(f"session: {reply['session'] or '-'}", highlight=False)
            else:
                console.print(reply["message"], highlight=False)

    command("pause", "pause", "Pause at the end of the current record.")
    command("resume", "resume", "Continue a paused session (signed with the rig's key).")
    command("abort", "abort", "Stop now: controlled stop, the run logged aborted.")
    command("estop", "emergency_stop", "Emergency stop: the table brakes.")
    command("state", "state", "The service's state, progress and session file.")

    @service_app.command("queue")
    def queue_cmd(
        sequence: Annotated[Path, typer.Argument(metavar="SEQUENCE.toml", help="the test sequence")],
        connect: ConnectOption = DEFAULT_ENDPOINT, key_file: KeyOption = None,
        table: Annotated[str | None, typer.Option(help="table URL (default: the sequence's table_url)")] = None,
        emulate: Annotated[bool, typer.Option(help="the service starts the emulated table")] = False,
        attended: Annotated[bool, typer.Option(help="the operator's steps wait for an answer from the console "
                                                    "(place the bodies, and per the sequence confirm each run and "
                                                    "say which bodies fell)")] = False,
        output: Annotated[Path | None, typer.Option("-o", "--output", help="new session file")] = None,
        speed: Annotated[float, typer.Option(parser=_parse_speed, metavar="FACTOR|max",
                                             help="with --emulate: controller time per real time, or max (virtual "
                                                  "time)")] = 1.0,
        key_passphrase: KeyPassphrase = None,
    ) -> None:
        """Queue a session on the service (signed): the operator starts it from the console."""
        from rig.service import ServiceClient, ServiceError

        use_key_passphrase(key_passphrase, key_file)
        try:
            with ServiceClient(connect, key_file) as client:
                number = client.queue(sequence, table=table, emulate=emulate, output=output, attended=attended,
                                      speed=speed)
        except ServiceError as exc:
            fail(str(exc))
        console.print(f"queued as session {number}: start it from the console", highlight=False)

    @service_app.command("token")
    def token_cmd(key_file: KeyOption = None, key_passphrase: KeyPassphrase = None) -> None:
        """Print the operator token the console's controls ask for: HMAC-SHA256(rig key, "operator-console")."""
        from protocols.signing_key import SigningKeyError
        from rig.console import token_from_key_file

        use_key_passphrase(key_passphrase, key_file)
        try:
            sys.stdout.write(token_from_key_file(key_file) + "\n")
        except SigningKeyError as exc:
            fail(str(exc))
    app.add_typer(service_app, name="service")
