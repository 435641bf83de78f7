"""``rig run``: a test sequence on the table (or the emulated one), logged to a new session file.

The orchestrator runs in a worker thread; this thread draws the progress (a bar for the run and one for the
session, a status line: table state, setpoint buffer, peak plate acceleration, detections), asks the operator's
questions and takes Ctrl-C: the first pauses at the end of the current record (then: resume, or end the
session there — it stays resumable; unattended, ``--yes``, too: Enter resumes), the second aborts at once
(controlled stop, the run marked ``aborted``), also at a prompt. An emulator started here runs in its own process
group (``rig.emulator``): the terminal's Ctrl-C reaches ``rig``, not the table.
Exit codes: 0 all runs done, 1 the session stopped early or a run is degraded (resumable with ``--resume``),
2 bad input.
"""

from __future__ import annotations

import os
import queue
import select
import signal
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, NoReturn

import typer
from rich.console import Group
from rich.live import Live
from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn, TimeRemainingColumn
from rich.prompt import Confirm, Prompt
from rich.text import Text

from rig.cli._common import EXIT_STOPPED, console, emit_json, err_console, fail, fail_with, require_file
from rig.cli.network import (
    INSECURE_NOTE,
    Insecure,
    NetworkConfig,
    TlsCa,
    TlsCert,
    TlsKey,
    configured_security,
    link_security,
    network_of,
    table_options,
)
from rig.cli.passphrase import KeyPassphrase, use_key_passphrase
from rig.cli.web import HttpName, HttpsCert, HttpsDir, HttpsKey, TokensOption, web_access
from rig.emulator import parse_speed

if TYPE_CHECKING:  # imported where used (ISSUE 16: `rig --help` must not load h5py, numpy, scipy, …)
    from analysis.table.network import NetworkSettings
    from protocols.zenoh import LinkSecurity
    from rig.orchestrator import Orchestrator, OrchestratorState
    from rig.orchestrator import Progress as RunProgress
    from rig.sequence import PlacedBody, PlannedRun, Sequence
    from rig.session import SessionLog

REFRESH = 8.0
"""Screen refreshes per second."""


# ----- the operator at this terminal ---------------------------------------------------------------------------


class TerminalOperator:
    """The operator's steps asked on this terminal: the orchestrator's thread posts a question, the screen's
    thread asks it (the live display paused) and posts the answer back."""

    def __init__(self) -> None:
        self.questions: queue.Queue[tuple[Callable[[], Any], queue.Queue[Any]]] = queue.Queue()

    def _ask(self, question: Callable[[], Any]) -> Any:
        answer: queue.Queue[Any] = queue.Queue(maxsize=1)
        self.questions.put((question, answer))
        result = answer.get()
        if isinstance(result, BaseException):
            raise result
        return result

    def place_bodies(self, prompt: str) -> None:
        from rig.orchestrator.states import OperatorDeclinedError

        def ask() -> None:
            if not Confirm.ask(f"[bold]{prompt}[/]\nBodies placed?", default=True):
                raise OperatorDeclinedError("bodies not placed")

        self._ask(ask)

    def confirm_run(self, run: PlannedRun, description: str) -> None:
        from rig.orchestrator.states import OperatorDeclinedError

        def ask() -> None:
            if not Confirm.ask(f"Run {run.plan_index + 1}: {description}. Start?", default=True):
                raise OperatorDeclinedError(f"run {run.plan_index + 1} not started")

        self._ask(ask)

    def which_fell(self, run: PlannedRun, bodies: tuple[PlacedBody, ...]) -> list[tuple[int, int]]:
        def ask() -> list[tuple[int, int]]:
            fell = []
            for body in bodies:
                answer = Prompt.ask(f"Body {body.body_id} ({body.name}): fell to the low side (+), the high side (-) "
                                    "or stood (0)?", choices=["+", "-", "0"], default="0")
                if answer != "0":
                    fell.append((body.body_id, 1 if answer == "+" else -1))
            return fell

        return self._ask(ask)


# ----- the screen ----------------------------------------------------------------------------------------------


class Screen:
    """Progress bars and the status line, drawn from the orchestrator's progress."""

    def __init__(self, progress: RunProgress) -> None:
        self.progress = progress
        self.bars = Progress(TextColumn("{task.description}"), BarColumn(), TaskProgressColumn(),
                             TimeRemainingColumn(), transient=False)
        self.session_task = self.bars.add_task("session", total=max(progress.runs_total, 1))
        self.run_task = self.bars.add_task("run", total=1)

    def render(self) -> Group:
        p = self.progress
        self.bars.update(self.session_task, completed=p.runs_done, total=max(p.runs_total, 1),
                         description=f"session {p.runs_done}/{p.runs_total}")
        label = f"run {p.run.plan_index + 1}" if p.run is not None else "run"
        self.bars.update(self.run_task, completed=p.samples_sent, total=max(p.samples_total, 1), description=label)
        status = Text.assemble(
            ("state ", "dim"), (p.state.value, "bold"), ("  table ", "dim"), (p.table_state or "-", ""),
            ("  buffer ", "dim"), (f"{p.buffer_depth}", ""), ("  peak ", "dim"), (f"{p.peak_accel / 9.81:.3f} g", ""),
            ("  overturns ", "dim"), (f"{p.detections}", ""), ("  ", ""), (p.message, "italic"))
        return Group(self.bars, status)


def resume_hint(path: Path, key_file: Path | None, yes: bool) -> str:
    """The command that continues the session file ``path`` on the table stored in it, with this one's key file and
    unattended if this one was."""
    return (f"rig run --resume {path}" + (f" --key-file {key_file}" if key_file is not None else "")
            + (" --yes" if yes else ""))


def run_session(sequence: Sequence, log: SessionLog, url: str, options: dict[str, Any], *, yes: bool,
                console: Any, with_outcome: bool = False, ending: list[str] | None = None) -> Any:
    """Play the session with the screen, the prompts and Ctrl-C handling (module docstring); whether every run of
    the plan is done (with ``with_outcome``: that and ``{"state", "message", "runs_done", "runs_total"}``). The final
    message is appended to ``ending`` if given."""
    from rig.orchestrator import Orchestrator, OrchestratorState

    operator = None if yes else TerminalOperator()
    orchestrator = Orchestrator(sequence, url, log, table_options=options, operator=operator)
    if options.get("insecure_plain_tcp"):
        orchestrator.log_event(INSECURE_NOTE)
    screen = Screen(orchestrator.progress)
    result: list[OrchestratorState | BaseException] = []

    def work() -> None:
        try:
            result.append(orchestrator.run())
        except BaseException as exc:
            result.append(exc)

    interrupts = [0]
    prompting = [False]  # this thread waits at a prompt: a second Ctrl-C interrupts it

    def on_sigint(signum: int, frame: object) -> None:
        interrupts[0] += 1
        if interrupts[0] == 1:
            orchestrator.pause()
        else:
            threading.Thread(target=orchestrator.abort, daemon=True).start()
            if prompting[0]:
                raise KeyboardInterrupt

    worker = threading.Thread(target=work, name="orchestrator")
    previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        with Live(screen.render(), console=console, refresh_per_second=REFRESH, transient=False) as live:
            worker.start()
            while worker.is_alive():
                live.update(screen.render())
                asked = _next_question(operator)
                if asked is not None:
                    live.stop()
                    prompting[0] = True
                    try:
                        _answer(*asked)
                    finally:
                        prompting[0] = False
                    live.start()
                if orchestrator.state is OrchestratorState.PAUSED:
                    live.stop()
                    prompting[0] = True
                    try:
                        _paused(orchestrator, interrupts, yes, console)
                    except KeyboardInterrupt:
                        pass  # the second Ctrl-C: the handler has aborted
                    finally:
                        prompting[0] = False
                    live.start()
                time.sleep(1 / REFRESH)
            live.update(screen.render())
    finally:
        signal.signal(signal.SIGINT, previous)
        worker.join()
    outcome = result[0]
    if isinstance(outcome, BaseException):
        raise outcome
    progress = orchestrator.progress
    console.print(f"\n[bold]{outcome.value}[/]: {progress.message}")
    if ending is not None:
        ending.append(progress.message)
    degraded = sorted(index + 1 for index, status in progress.outcomes.items() if status == "degraded")
    if degraded:
        console.print(f"[bold yellow]degraded[/]: run(s) {', '.join(map(str, degraded))} played, but not cleanly "
                      "(their events say why): left out of Fig. 13; --resume plays them again")
    complete = outcome is OrchestratorState.DONE and progress.runs_done == progress.runs_total
    if not with_outcome:
        return complete
    return complete, {"state": outcome.value, "message": progress.message, "runs_done": progress.runs_done,
                      "runs_total": progress.runs_total, "degraded_runs": degraded}


def _end_disk_full(path: Path) -> NoReturn:
    """Exit :data:`EXIT_STOPPED` after a session the disk ended. HDF5 frees a file whose last writes failed at the
    interpreter's final garbage collection and crashed there (a segmentation fault), after everything was said and
    every committed row was on disk: this exit skips it."""
    console.print(f"the session stopped early: the rows written are kept; free some space, then `rig sessions "
                  f"recover {path}` if it says so, and continue with rig run --resume {path}")
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(EXIT_STOPPED)


def _next_question(operator: TerminalOperator | None) -> tuple[Callable[[], Any], queue.Queue[Any]] | None:
    if operator is None:
        return None
    try:
        return operator.questions.get_nowait()
    except queue.Empty:
        return None


def _answer(question: Callable[[], Any], answer: queue.Queue[Any]) -> None:
    from rig.orchestrator.states import OperatorDeclinedError

    try:
        answer.put(question())
    except (OperatorDeclinedError, EOFError, KeyboardInterrupt) as exc:
        answer.put(exc if isinstance(exc, OperatorDeclinedError) else OperatorDeclinedError("no answer"))


def _paused(orchestrator: Orchestrator, interrupts: list[int], yes: bool, console: Any) -> None:
    """Paused at the end of a record: resume, or end the session here (resumable)."""
    if interrupts[0] >= 2:
        return
    if yes:
        _paused_unattended(orchestrator, interrupts, console)
        return
    try:
        go_on = Confirm.ask("Paused at the end of the record. Resume?", default=True)
    except (EOFError, KeyboardInterrupt):
        go_on = False
    if go_on:
        interrupts[0] = 0
        orchestrator.resume()
    else:
        orchestrator.abort()


def _paused_unattended(orchestrator: Orchestrator, interrupts: list[int], console: Any) -> None:
    """``--yes`` and paused: wait — Enter resumes, a second Ctrl-C ends the session here (resumable), and so does
    a resume or abort from the console or the service. Standard input that is closed is not read again."""
    from rig.orchestrator import OrchestratorState

    console.print("paused at the end of the record: press Enter to resume, Ctrl-C again to end the session here "
                  "(rig run --resume continues it)")
    reading = True
    while orchestrator.state is OrchestratorState.PAUSED and interrupts[0] < 2:
        if not reading:
            time.sleep(0.25)
            continue
        try:
            ready, _, _ = select.select([sys.stdin], [], [], 0.25)
        except (OSError, ValueError, TypeError):  # no standard input to wait on
            reading = False
            continue
        if ready:
            if sys.stdin.readline():
                interrupts[0] = 0
                orchestrator.resume()
                return
            reading = False  # end of input: only Ctrl-C, the console or the service go on from here


def _configured_network(network: NetworkSettings | None, sequence: Path | None) -> NetworkSettings | None:
    """The ``[network]`` of ``--rig-config`` (``network``), else that of the sequence's ``[rig] config`` (None
    without a sequence: ``--resume``); exits 2 naming ``FILE:LINE`` when the sequence or its ``[network]`` is
    bad."""
    if network is not None or sequence is None:
        return network
    from rig.sequence import SequenceError, load_sequence

    try:
        return load_sequence(sequence).table.network
    except SequenceError as exc:
        fail_with(exc)


def _table_url(table: str | None, sequence: Path | None) -> str:
    """``--table``, else the sequence's ``table_url`` (lower case; "" when neither names one)."""
    if table is None and sequence is not None:
        from rig.sequence import SequenceError, load_sequence

        try:
            table = load_sequence(sequence).table_url
        except SequenceError as exc:
            fail_with(exc)
    return (table or "").lower()


def _service_security(given: LinkSecurity, network: NetworkSettings | None, sequence: Path | None) -> LinkSecurity:
    """The TLS identity for the link to a rig service on a ``tls/`` endpoint: ``given`` (``--tls-*``), else the
    configured one (:func:`_configured_network`)."""
    if given.tls is not None:
        return given
    configured = _configured_network(network, sequence)
    return given if configured is None else configured_security(given, configured)


def register(app: typer.Typer) -> None:
    """Add ``rig run``."""

    @app.command("run")
    def run(sequence_file: Annotated[Path | None, typer.Argument(metavar="SEQUENCE.toml",
                                                                 help="the test sequence (not with --resume)")] = None,
            table: Annotated[str | None, typer.Option(help="table URL, e.g. mavlink://192.168.1.20:14600")] = None,
            emulate: Annotated[bool, typer.Option(help="start the emulated table (MAVLink on loopback) and "
                                                       "stop it after")] = False,
            output: Annotated[Path | None, typer.Option("-o", "--output", help="new session file (default: "
                                                        "session-DATE-TIME-NAME.h5 here)")] = None,
            resume: Annotated[Path | None, typer.Option(help="continue this session file from its first run "
                                                             "that did not complete")] = None,
            yes: Annotated[bool, typer.Option("--yes", "-y", help="unattended: no operator prompts")] = False,
            key_file: Annotated[Path | None, typer.Option(help="signing key file (default: "
                                                               "$SHAKETABLE_MAVLINK_KEY)")] = None,
            speed: Annotated[float | None, typer.Option(parser=parse_speed, metavar="FACTOR|max",
                                                        help="with --emulate: controller time per real time, or max "
                                                             "(virtual time: as fast as the emulator computes); "
                                                             "default 1, or with --resume the session's")] = None,
            service: Annotated[str | None, typer.Option(help="have a rig service (rig serve) at this zenoh "
                                                             "endpoint run it, e.g. tcp/127.0.0.1:7447")] = None,
            console_at: Annotated[str | None, typer.Option("--console", help="serve the operator's console (live "
                                                           "web page and controls) at HOST:PORT, e.g. "
                                                           "127.0.0.1:8080")] = None,
            console_linger: Annotated[float | None, typer.Option(
                "--console-linger", metavar="SECONDS", min=0.0,
                help="with --console: close the console SECONDS after the session ends (default: it stays up "
                     "showing the final state and the report until Ctrl-C)")] = None,
            as_json: Annotated[bool, typer.Option("--json", help="print one JSON object (the session's outcome) "
                                                  "on stdout, the progress on stderr; needs --yes")] = False,
            tls_ca: TlsCa = None, tls_cert: TlsCert = None, tls_key: TlsKey = None,
            insecure_plain_tcp: Insecure = False, key_passphrase: KeyPassphrase = None,
            http_name: HttpName = None, tokens: TokensOption = None, https_cert: HttpsCert = None,
            https_key: HttpsKey = None, https_dir: HttpsDir = None, rig_config: NetworkConfig = None,
            ) -> None:
        """Run a test sequence on the table, logging every run to a session file. With --resume the session
        continues on the table it ran on (its URL, or the emulated table at its speed) unless --table or --emulate
        says otherwise."""
        for given in (sequence_file, resume, key_file):
            if given is not None:
                require_file(given)
        use_key_passphrase(key_passphrase, key_file)
        if as_json and (not yes or console_at is not None or service is not None):
            fail("--json needs --yes (no operator prompts) and is not taken with --service or --console")
        speed_given = speed
        speed = 1.0 if speed is None else speed
        security = link_security(tls_ca, tls_cert, tls_key, insecure_plain_tcp)
        network = network_of(rig_config)
        if service is not None and service.lower().startswith("tls/"):
            security = _service_security(security, network, sequence_file)
        web = (http_name, tokens, https_cert, https_key, https_dir)
        if console_at is not None:
            from rig.cli.with_console import run_with_console

            configured = _configured_network(network, sequence_file)
            access = web_access(*web, None if configured is None else configured.console)
            if service is None and configured is not None and _table_url(table, sequence_file).startswith("zenoh://"):
                security = configured_security(security, configured)  # for the in-process service's table
            raise typer.Exit(run_with_console(console_at, sequence_file, table=table, emulate=emulate, output=output,
                                              resume=resume, yes=yes, console=console, key_file=key_file,
                                              speed=speed, service=service, linger_s=console_linger,
                                              security=security, access=access))
        if any(web):
            fail("--http-name, --tokens, --https-cert, --https-key and --https-dir are the console's: give --console "
                 "HOST:PORT too")

        from rig.emulator import EmulatorError
        from rig.orchestrator.bodies import BodiesMismatchError
        from rig.orchestrator.setup import (
            CountersNotWrittenError,
            NoTableError,
            TableUnreachableError,
            choose_table,
            create_log,
            default_session_path,
            load_checked,
            resume_log,
            resumed,
            table_for,
            write_emulator_counters,
        )
        from rig.sequence import SequenceError
        from rig.session import SessionError

        if service is not None:
            from rig.cli.serve import drive_service

            raise typer.Exit(drive_service(service, sequence_file, table=table, emulate=emulate, output=output,
                                           resume=resume, yes=yes, console=console, key_file=key_file, speed=speed,
                                           security=security))
        screen = err_console if as_json else console
        ending: list[str] = []
        try:
            stored = None
            if resume is not None:
                sequence, stored = resumed(resume)
                path = resume
            else:
                if sequence_file is None:
                    fail("give a SEQUENCE.toml (or --resume SESSION.h5)")
                sequence = load_checked(sequence_file)
                path = output or default_session_path(sequence)
            choice = choose_table(sequence, table, emulate, speed_given, stored)
            url_given = choice.url or sequence.table_url
            if url_given is not None and url_given.lower().startswith("zenoh://"):  # else [network] does not apply
                security = configured_security(security, sequence.table.network if network is None else network)
            link = {} if choice.emulate else table_options(url_given, security)
            with table_for(sequence, choice.url, choice.emulate, key_file, choice.speed, link) as (url, options,
                                                                                                  counters):
                log = resume_log(path) if resume is not None else create_log(sequence, path, choice)
                screen.print(f"session file: {path}", highlight=False)
                try:
                    complete, outcome = run_session(sequence, log, url, options, yes=yes, console=screen,
                                                    with_outcome=True, ending=ending)
                finally:
                    log.close()
            emulator_file = None
            if counters is not None:
                try:
                    emulator_file = write_emulator_counters(path, counters())
                except CountersNotWrittenError as exc:  # the session itself is as it ended: end as it ends
                    err_console.print(f"warning: {exc}", highlight=False, soft_wrap=True)
        except NoTableError:
            fail("no table: give --table URL (or table_url in the sequence), or --emulate")
        except (SequenceError, SessionError, EmulatorError, TableUnreachableError, BodiesMismatchError) as exc:
            if ending and ending[-1].startswith("disk full:"):
                _end_disk_full(path)
            fail_with(exc)
        hint = None if complete else resume_hint(path, key_file, yes)
        if as_json:
            emit_json({"session": str(path), "complete": complete, **outcome, "resume": hint,
                       "emulator_counters": None if emulator_file is None else str(emulator_file)})
        elif hint is not None:
            console.print(f"the session stopped early: continue it with {hint}", highlight=False,
                          soft_wrap=True)  # a command is never broken across lines
        if not complete:
            if ending and ending[-1].startswith("disk full:"):
                _end_disk_full(path)
            raise typer.Exit(code=EXIT_STOPPED)
