"""``rig serve`` in its own process, driven over zenoh from this one: pause at the end of a record and resume, abort
mid-record, and the refusals (nothing running, a bad sequence, an unsigned or replayed motion command, a second
session). The sessions run on the emulated table (``"emulate": true``: the service starts ``python -m sim_table``)."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import h5py
import pytest
import zenoh

from protocols.signing_key import write_signing_key
from protocols.zenoh import session_config
from protocols.zenoh.auth import Signer
from rig.service import ServiceClient, ServiceError, ServiceKeys, ServiceUnavailableError
from rig.service.wire import decode_reply, encode_request, sign
from rig.session import read_session
from tests.helpers.cli import rig
from tests.helpers.processes import child_of, free_port, running, serve_command
from tests.helpers.sequences import TINY

pytestmark = pytest.mark.integration  # starts processes or opens sockets (tests/conftest.py)

SETTLE_LINE = 10
"""The line of ``settle_s`` in :data:`TINY`."""



class Service:
    """The running ``rig serve``: its endpoint, sessions directory, key file and log; with ``http``
    (``HOST:PORT``) also its console, waited for until it serves."""

    def __init__(self, root: Path, http: str | None = None) -> None:
        self.root = root
        self.sessions = root / "sessions"
        self.key_file = root / "rig.key"
        write_signing_key(self.key_file)
        self.endpoint = f"tcp/127.0.0.1:{free_port()}"
        self.log = root / "serve.log"
        env = {k: v for k, v in os.environ.items() if k != "SHAKETABLE_MAVLINK_KEY"}
        with self.log.open("w") as log:
            self.proc = subprocess.Popen([*serve_command(), "--listen", self.endpoint, "--sessions-dir",
                                          str(self.sessions), "--key-file", str(self.key_file),
                                          *(["--http", http] if http else [])],
                                         stdout=subprocess.DEVNULL, stderr=log, env=env, cwd=root)
        deadline = time.monotonic() + 60
        while "listening on" not in (text := self.log.read_text()) or (http and "console at" not in text):
            assert self.proc.poll() is None, f"rig serve exited: {self.log.read_text()}"
            assert time.monotonic() < deadline, f"rig serve did not start: {self.log.read_text()}"
            time.sleep(0.05)

    def client(self, **options: Any) -> ServiceClient:
        return ServiceClient(self.endpoint, self.key_file, **options)

    def stop(self) -> str:
        self.proc.send_signal(signal.SIGTERM)
        try:
            self.proc.wait(60)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            raise
        return self.log.read_text()


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Service]:
    running = Service(tmp_path_factory.mktemp("serve"))
    try:
        yield running
    finally:
        log = running.stop()
    assert running.proc.returncode == 0, log
    assert "stopped" in log


@pytest.fixture
def client(service: Service) -> Iterator[ServiceClient]:
    with service.client() as connected:
        wait_until(lambda: not connected.state()["active"], 60)  # the previous test's session has let go
        yield connected


@pytest.fixture
def tiny(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    return path


def wait_until(predicate: Callable[[], bool], timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.05)


def wait_status(feed: Any, predicate: Callable[[dict[str, Any]], bool], timeout: float = 60) -> dict[str, Any]:
    """The first status from the service's telemetry that satisfies ``predicate``."""
    deadline = time.monotonic() + timeout
    for status in feed:
        if predicate(status):
            return status
        assert time.monotonic() < deadline, f"timed out; last status: {status}"
    raise AssertionError("unreachable")


def test_commands_with_nothing_running_are_refused(service: Service, client: ServiceClient) -> None:
    for command in (client.pause, client.resume, client.abort, client.emergency_stop):
        with pytest.raises(ServiceError, match="no session is running"):
            command()
    state = client.state()
    assert state["ok"] and not state["active"]
    port = free_port()
    with pytest.raises(ServiceUnavailableError, match=f"no rig service at tcp/127.0.0.1:{port}"):
        ServiceClient(f"tcp/127.0.0.1:{port}", connect_timeout=0.5)


def test_a_bad_sequence_is_refused_naming_its_line(service: Service, client: ServiceClient, tmp_path: Path) -> None:
    before = sorted(service.sessions.glob("*.h5"))
    bad = tmp_path / "bad.toml"
    bad.write_text(TINY.replace("settle_s = 0.3", "settle_s = -1"))
    with pytest.raises(ServiceError, match=f"{bad}:{SETTLE_LINE}: drive.settle_s: expected"):
        client.start(bad, emulate=True)
    with pytest.raises(ServiceError, match=f"^bad.toml:{SETTLE_LINE}: drive.settle_s: expected"):
        client.start(sequence_toml=bad.read_text(), sequence_name="bad", emulate=True)
    good = tmp_path / "tiny.toml"
    good.write_text(TINY)
    with pytest.raises(ServiceError, match="give a table URL"):
        client.start(good)  # neither a table nor emulate
    assert not client.state()["active"]
    assert sorted(service.sessions.glob("*.h5")) == before


def test_motion_commands_must_be_signed_and_fresh(service: Service, tiny: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("SHAKETABLE_MAVLINK_KEY", raising=False)
    with ServiceClient(service.endpoint) as unsigned:
        with pytest.raises(ServiceError, match="start refused: not signed"):
            unsigned.start(tiny, emulate=True)
        with pytest.raises(ServiceError, match="resume refused: not signed"):
            unsigned.resume()
        unsigned.state()  # pause, abort, estop and state need no key
    # a signed resume replayed: the first passes the signature check (then: nothing to resume), the copy is stale
    key = ServiceKeys.for_rig().commands["resume"]
    payload = encode_request("resume", {})
    attachment = sign(Signer(bytes.fromhex(service.key_file.read_text().strip()), 7), key, payload)
    session = zenoh.open(session_config(connect=[service.endpoint]))
    try:
        wait_until(lambda: session.declare_querier(key).matching_status.matching, 5)
        answers = []
        for _ in range(2):
            replies = [r for r in session.get(key, payload=payload, attachment=attachment, timeout=5) if r.ok]
            answers.append(decode_reply(replies[0].ok.payload.to_bytes())["message"])
    finally:
        session.close()
    assert "no session is running" in answers[0]
    assert "stale signature" in answers[1]


def test_pause_and_resume_over_zenoh_from_a_second_process(service: Service, client: ServiceClient,
                                                           tiny: Path) -> None:
    with client.telemetry() as feed:
        path = Path(client.start(tiny, emulate=True))
        assert path.parent == service.sessions
        status = wait_status(feed, lambda s: s["session"] == str(path) and s["state"] == "running"
                             and s["progress"]["samples_sent"] > 300)
        assert status["progress"]["runs_done"] == 0  # the first record plays
        assert client.pause()["ok"]
        with pytest.raises(ServiceError, match="a session is running"):
            client.start(tiny, emulate=True)
        paused = wait_status(feed, lambda s: s["state"] != "running")
        assert paused["state"] == "paused"
        assert paused["progress"]["runs_done"] == 1 and paused["progress"]["outcomes"] == {"0": "completed"}
        runs = read_session(path, data=False)["runs"]
        assert [r["status"] for r in runs] == ["completed"]  # paused after the first record, the second not begun
        time.sleep(1.0)
        state = client.state()
        assert state["state"] == "paused" and state["session"] == str(path)
        assert len(read_session(path, data=False)["runs"]) == 1
        assert client.resume()["ok"]
        wait_status(feed, lambda s: s["state"] == "running")
        done = wait_status(feed, lambda s: s["state"] in ("done", "faulted"))
    assert done["state"] == "done" and done["progress"]["runs_done"] == 2
    seqs = [paused["seq"], done["seq"]]
    assert seqs == sorted(seqs)
    wait_until(lambda: not client.state()["active"], 30)
    runs = read_session(path)["runs"]
    assert [r["status"] for r in runs] == ["completed", "completed"]
    assert [r["plan_index"] for r in runs] == [0, 1]


def test_abort_during_a_run_logs_it_aborted(client: ServiceClient, tiny: Path, tmp_path: Path) -> None:
    output = tmp_path / "aborted.h5"
    with client.telemetry() as feed:
        assert client.start(tiny, emulate=True, output=output) == str(output)
        wait_status(feed, lambda s: s["state"] == "running" and s["progress"]["samples_sent"] > 300)
        assert "abort requested" in client.abort()["message"]
        final = wait_status(feed, lambda s: s["state"] in ("done", "faulted"), 30)
    assert final["state"] == "done" and final["progress"]["runs_done"] == 0
    wait_until(lambda: not client.state()["active"], 30)
    runs = read_session(output, data=False)["runs"]
    assert [r["status"] for r in runs] == ["aborted"]
    assert "abort" in runs[0]["attrs"]["reason"]


def test_a_control_a_client_refused_is_logged_and_never_acted_on(client: ServiceClient, tiny: Path,
                                                                 tmp_path: Path) -> None:
    """The console refuses a viewer's abort and passes it on (``refused``): the service answers it refused, the
    session plays on to its end, and the run's events name the viewer, signed."""
    output = tmp_path / "watched.h5"
    with client.telemetry() as feed:
        client.start(tiny, emulate=True, output=output)
        wait_status(feed, lambda s: s["state"] == "running" and s["progress"]["samples_sent"] > 300)
        client.refused("abort", "console browser session 2 with the viewer token of 'tablet'",
                       "a viewer may watch only")
        final = wait_status(feed, lambda s: s["state"] in ("done", "faulted") and not s["active"], 120)
    assert final["state"] == "done" and final["progress"]["runs_done"] == 2, final
    runs = read_session(output)["runs"]
    assert [r["status"] for r in runs] == ["completed", "completed"]
    (logged,) = [e["text"] for r in runs for e in r["events"] if " control " in e["text"]]
    assert " control abort from console browser session 2 with the viewer token of 'tablet' (signed: " in logged
    assert logged.endswith(": refused: refused by the console: a viewer may watch only"), logged


def test_shutdown_aborts_the_running_session(tmp_path: Path, tiny: Path) -> None:
    own = Service(tmp_path)
    try:
        with own.client() as connected, connected.telemetry() as feed:
            path = Path(connected.start(tiny, emulate=True))
            wait_status(feed, lambda s: s["state"] == "running" and s["progress"]["samples_sent"] > 300)
            log = own.stop()
    finally:
        if own.proc.poll() is None:
            own.stop()
    assert own.proc.returncode == 0, log
    assert "shutting down: the running session is aborted" in log and "stopped" in log
    runs = read_session(path, data=False)["runs"]
    assert [r["status"] for r in runs] == ["aborted"]


def test_the_console_the_service_started_ends_when_the_service_is_killed(tmp_path: Path) -> None:
    """``kill -9`` of ``rig serve --http``: the console it started (its child ``python -m rig.console``, in a
    session of its own) sees its parent gone and stops, leaving no process holding the HTTP port."""
    own = Service(tmp_path, http=f"127.0.0.1:{free_port()}")
    console = child_of(own.proc, b"rig.console")
    try:
        own.proc.kill()
        own.proc.wait()
        deadline = time.monotonic() + 30
        while running(console, b"rig.console"):
            assert time.monotonic() < deadline, f"the console outlived rig serve: {own.log.read_text()}"
            time.sleep(0.1)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.kill(console, signal.SIGKILL)


def test_the_service_needs_the_rig_key_unless_told_otherwise(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from rig.service import OrchestratorService

    monkeypatch.delenv("SHAKETABLE_MAVLINK_KEY", raising=False)
    with pytest.raises(ServiceError, match="needs the rig's key"):
        OrchestratorService(f"tcp/127.0.0.1:{free_port()}", sessions_dir=tmp_path)
    with OrchestratorService(f"tcp/127.0.0.1:{free_port()}", sessions_dir=tmp_path, require_auth=False) as bench:
        assert not bench.authenticated
        assert bench.snapshot()["state"] == "idle"


def test_rig_run_service_drives_the_service_to_the_end(service: Service, client: ServiceClient, tiny: Path,
                                                      tmp_path: Path) -> None:
    """``rig run --service``: the sequence runs on the service (which starts its own emulator, here in virtual
    time: ``--speed max`` travels in the start request), the command line follows its telemetry and exits 0 when
    every run is done."""
    output = tmp_path / "via-service.h5"
    done = rig("run", str(tiny), "--service", service.endpoint, "--emulate", "--speed", "max", "--yes", "--key-file",
               str(service.key_file), "-o", str(output))
    assert done.exit_code == 0, done.stdout + done.stderr
    runs = read_session(output, data=False)["runs"]
    assert [(r["plan_index"], r["status"]) for r in runs] == [(0, "completed"), (1, "completed")]


@pytest.mark.parametrize(("speed", "refused"), [(2.5, None), ("max", None), (0, "speed must be a number > 0"),
                                                (float("nan"), "speed must be"), ("fast", "speed must be"),
                                                (True, "speed must be")])
def test_the_start_request_carries_a_speed_or_max(tmp_path: Path, speed: object, refused: str | None) -> None:
    """A start request's ``speed``: controller time per real time, or ``"max"`` (virtual time, math.inf inside),
    which round-trips through the request's args; anything else is refused naming the field."""
    import math

    from rig.service.session import StartRefusedError, StartRequest

    args = {"sequence": "tiny.toml", "emulate": True, "speed": speed}
    if refused is not None:
        with pytest.raises(StartRefusedError, match=refused):
            StartRequest.from_args(args, tmp_path)
        return
    request = StartRequest.from_args(args, tmp_path)
    assert request.speed == (math.inf if speed == "max" else speed)
    assert StartRequest.from_args(request.to_args(), tmp_path) == request


FORGED_SOURCE = ("console page, browser 127.0.0.1:5 (Firefox/120.0)\n"
                 "2026-11-27T09:00:00Z control estop from console page: accepted")
"""What a local process without the key claimed to be (issue 25.9): a newline and a fake line after it."""


def test_a_queued_attended_session_is_started_and_answered_and_logged_as_the_transport_says(
        service: Service, client: ServiceClient, tiny: Path, tmp_path: Path) -> None:
    """``queue`` (signed; ``rig service queue``) lines a session up without starting it; ``start {"queued": id}``
    starts it; an attended session waits at "place the bodies" for ``answer`` (signed, the prompt's id). Every
    control is in the session's events with the source the transport vouches for: an unsigned request's claimed
    source is not written, a signed one's is, escaped on one line."""
    output = tmp_path / "attended.h5"
    queued = rig("service", "queue", str(tiny), "--connect", service.endpoint, "--key-file", str(service.key_file),
                 "--emulate", "--attended", "--speed", "max", "-o", str(output))
    assert queued.exit_code == 0, queued.stdout + queued.stderr
    number = int(queued.stdout.split("queued as session ")[1].split(":")[0])
    state = client.state()
    assert state["queue"] == [{"id": number, "name": "tiny.toml", "emulate": True, "attended": True}]
    assert not state["active"] and not output.exists()
    with ServiceClient(service.endpoint) as unsigned:
        with pytest.raises(ServiceError, match="queue refused: not signed"):
            unsigned.queue(tiny, emulate=True)
        with pytest.raises(ServiceError, match="start refused: not signed"):
            unsigned.start_queued(number)
        with pytest.raises(ServiceError, match="answer refused: not signed"):
            unsigned.answer(1)
    with pytest.raises(ServiceError, match="no session 999 in the queue"):
        client.start_queued(999)
    with client.telemetry() as feed:
        assert client.start_queued(number) == str(output)
        waiting = wait_status(feed, lambda s: s["session"] == str(output) and s.get("prompt") is not None)
        prompt = waiting["prompt"]
        assert waiting["state"] == "waiting for the operator" and prompt["kind"] == "place_bodies"
        assert waiting["queue"] == []
        time.sleep(0.5)
        assert client.state()["state"] == "waiting for the operator"  # it waits: nothing answered yet

        peer = zenoh.open(session_config(connect=[service.endpoint]))  # a local process without the key
        try:
            key = ServiceKeys.for_rig().commands["pause"]
            replies = list(peer.get(key, payload=encode_request("pause", {"source": FORGED_SOURCE}), timeout=5))
            assert decode_reply(replies[0].ok.payload.to_bytes())["ok"]  # stopping never waits for a key
        finally:
            peer.close()
        client.resume(source="test: cancel the pause")
        with pytest.raises(ServiceError, match="not the one waiting"):
            client.answer(prompt["id"] + 1)
        assert "answered: done" in client.answer(prompt["id"], "done", source="test operator")["message"]
        done = wait_status(feed, lambda s: s["session"] == str(output) and s["state"] in ("done", "faulted"), 120)
    assert done["state"] == "done", done
    wait_until(lambda: not client.state()["active"], 30)
    with h5py.File(output, "r") as h5:
        events = [text.decode() for run in h5["runs"].values() for _, text in run["events"][:]]
    controls = [e for e in events if " control " in e]
    assert len(controls) == 4, events
    assert controls[0].endswith(" control pause from unsigned zenoh client: accepted"), controls
    assert " control resume from test: cancel the pause (signed: rig key holder " in controls[1]
    assert " control answer from rig key holder " in controls[2] and " refused: answer: prompt " in controls[2]
    assert " control answer from test operator (signed: rig key holder " in controls[3]
    assert controls[3].endswith("accepted")
    assert not any("Firefox" in e or "estop" in e or "\n" in e for e in events)
