"""The console and the service attacked as issue 25 did, without a browser: Slowloris (slow and excess connections),
a forged and newline-injected audit source, the operator token kept out of page scripts' reach (HttpOnly
SameSite=Strict browser session + CSRF header) and a strict Content-Security-Policy on every response; and the
console's new state: faults filed under their run, the attended session's operator answered from another thread."""

from __future__ import annotations

import asyncio
import json
import secrets
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
import zenoh
from starlette.testclient import TestClient

from protocols.signing_key import write_signing_key
from protocols.zenoh import session_config
from rig.console import Console, create_app, operator_token
from rig.console.guard import ConnectionGuard
from rig.console.server import console_server
from rig.console.state import ConsoleState
from rig.orchestrator import OperatorDeclinedError
from rig.service import OrchestratorService, ServiceClient, ServiceKeys
from rig.service.audit import escaped
from rig.service.operator import AnswerRefusedError, RemoteOperator
from rig.service.wire import decode_reply, encode_request
from tests.helpers.console import HOST, SAME, RecordingControls
from tests.helpers.processes import free_port

# ----- 25.10: the token out of scripts' reach, CSP ----------------------------------------------------------------


def test_every_response_carries_a_strict_content_security_policy(monkeypatch: pytest.MonkeyPatch,
                                                                  tmp_path: Path) -> None:
    console = Console(RecordingControls(), operator_token(b"k" * 32), allowed_hosts={HOST})
    report = tmp_path / "s.console-report.html"
    report.write_text("<html><body><script>parent.pwned = 1</script></body></html>")
    monkeypatch.setattr("rig.console.app._report_of", lambda console, session: report)
    client = TestClient(create_app(console), base_url=f"http://{HOST}")
    with client:
        for path in ("/", "/static/console.js", "/api/state", "/api/session", "/nope"):
            policy = client.get(path).headers["content-security-policy"]
            directives = dict(d.strip().split(" ", 1) for d in policy.split(";"))
            assert directives["script-src"] == "'self'", (path, policy)  # no 'unsafe-inline', no other origin
            assert directives["default-src"] == "'none'" and directives["frame-ancestors"] == "'none'"
            assert client.get(path).headers["x-content-type-options"] == "nosniff"
        client.portal.call(console.deliver, "status", {"state": "done", "session": str(tmp_path / "s.h5"),
                                                       "active": False, "t_ns": 1})
        served = client.get("/report")
        assert served.status_code == 200
        policy = served.headers["content-security-policy"]
        assert policy.startswith("sandbox;") and "script-src" not in policy  # no script runs, opaque origin
        assert "default-src 'none'" in policy


def test_the_token_opens_an_httponly_samesite_strict_session_used_with_a_csrf_header() -> None:
    controls = RecordingControls()
    token = operator_token(secrets.token_bytes(32))
    console = Console(controls, token, allowed_hosts={HOST})
    client = TestClient(create_app(console), base_url=f"http://{HOST}")
    with client:
        assert client.get("/api/session").json() == {"unlocked": False}
        wrong = client.post("/api/token", headers={**SAME, "X-Operator-Token": "0" * 64})
        assert wrong.status_code == 403 and "set-cookie" not in wrong.headers
        unlocked = client.post("/api/token", headers={**SAME, "X-Operator-Token": token})
        cookie = unlocked.headers["set-cookie"]
        attributes = {a.strip().split("=")[0].lower(): a for a in cookie.split(";")}
        assert "httponly" in attributes and attributes["samesite"].strip().lower() == "samesite=strict"
        assert token not in cookie and token not in unlocked.text  # the token is not handed back
        csrf = unlocked.json()["csrf"]
        # the cookie alone (what another site's form or an injected <img> would send) is refused
        assert client.post("/api/control/pause", headers=SAME).status_code == 403
        assert client.post("/api/control/pause", headers={**SAME, "X-Console-CSRF": "x" * 43}).status_code == 403
        assert controls.calls == []
        sent = client.post("/api/control/pause", headers={**SAME, "X-Console-CSRF": csrf})
        assert sent.status_code == 200, sent.text
        assert controls.calls[-1][1].startswith("console browser session 1, unlocked ")
        assert controls.calls[-1][1].endswith("from testclient (testclient) with the operator token of 'rig key'")
        assert client.get("/api/session").json() == {"unlocked": True, "csrf": csrf, "session": 1,
                                                     "role": "operator"}
        # a queued session started, a prompt answered: the body's arguments go to the service
        client.post("/api/control/start", headers={**SAME, "X-Console-CSRF": csrf}, content=b'{"queued": 3}')
        client.post("/api/control/answer", headers={**SAME, "X-Console-CSRF": csrf},
                    content=json.dumps({"prompt": 5, "reply": "done", "fell": [[2, -1]]}))
        assert controls.args[-2:] == [{"queued": 3}, {"prompt": 5, "reply": "done", "fell": [[2, -1]]}]
        junk = client.post("/api/control/answer", headers={**SAME, "X-Console-CSRF": csrf}, content=b"[1, 2]")
        assert junk.status_code == 400
        huge = client.post("/api/control/answer", headers={**SAME, "X-Console-CSRF": csrf}, content=b" " * 5000)
        assert huge.status_code == 400
        locked = client.post("/api/lock", headers={**SAME, "X-Console-CSRF": csrf})
        assert locked.status_code == 200
        assert client.post("/api/control/pause", headers={**SAME, "X-Console-CSRF": csrf}).status_code == 403
        assert client.get("/api/session").json() == {"unlocked": False}


# ----- 25.8: Slowloris ---------------------------------------------------------------------------------------------


@pytest.fixture
def guarded_console() -> Iterator[tuple[str, int, ConnectionGuard, list[str]]]:
    """The console's real server (uvicorn with the guard) on a free loopback port, in a thread: host, port, the
    guard (1 s request timeout, 8 connections per client, 32 in all) and what it logged."""
    logged: list[str] = []
    guard = ConnectionGuard(logged.append, timeout=1.0, per_client=8, total=32)
    console = Console(RecordingControls(), None)
    port = free_port()
    server = console_server(console, "127.0.0.1", port, guard=guard)
    thread = threading.Thread(target=lambda: asyncio.run(server.serve()), daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not server.started:
        assert time.monotonic() < deadline and thread.is_alive(), "the console did not start"
        time.sleep(0.02)
    try:
        yield "127.0.0.1", port, guard, logged
    finally:
        server.should_exit = True
        thread.join(10)


def http_get(host: str, port: int, path: str) -> tuple[int, bytes]:
    with socket.create_connection((host, port), timeout=10) as conn:
        conn.sendall(f"GET {path} HTTP/1.1\r\nHost: {host}:{port}\r\nConnection: close\r\n\r\n".encode())
        data = b""
        while chunk := conn.recv(65536):
            data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    return int(head.split()[1]), body


def closed_by_server(conn: socket.socket) -> bool:
    """The server closed ``conn`` (within the socket's timeout)."""
    try:
        return conn.recv(1) == b""
    except ConnectionResetError:
        return True
    except TimeoutError:
        return False


@pytest.mark.integration
def test_slow_and_excess_connections_are_closed_and_logged_once(
        guarded_console: tuple[str, int, ConnectionGuard, list[str]]) -> None:
    host, port, guard, logged = guarded_console
    held = []
    for _ in range(60):  # Slowloris: a request's first header line, then nothing
        conn = socket.create_connection((host, port), timeout=10)
        conn.sendall(f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nX-a: ".encode())
        held.append(conn)
    try:
        status, body = http_get(host, port, "/api/state")  # the operator's page is still answered
        assert status == 200 and json.loads(body)["connections"]["evicted"] >= 52
        assert guard.stats()["open"] <= 8
        # the connections still held are closed once their request is 1 s late
        assert all(closed_by_server(conn) for conn in held[-7:])
        assert guard.counts["slow"] >= 1
    finally:
        for conn in held:
            conn.close()
    assert len([line for line in logged if "oldest still waiting" in line]) == 1, logged
    assert len([line for line in logged if "did not arrive within 1 s" in line]) == 1, logged
    assert len(logged) == 2


# ----- 25.9: the audit log's source --------------------------------------------------------------------------------


def test_escaped_text_is_one_line() -> None:
    assert escaped("a\nb\r\x1b[31m\u2028c\\n") == "a\\x0ab\\x0d\\x1b[31m\\u2028c\\\\n"
    assert escaped("x" * 300).endswith("…") and len(escaped("x" * 300)) == 201
    assert escaped("console browser session 1 (HeadlessChrome/150.0)") == \
        "console browser session 1 (HeadlessChrome/150.0)"


FORGED = ("console page, browser 127.0.0.1:5 (Firefox/120.0)\n"
          "2026-11-27T09:00:00Z control estop from console page: accepted")


@pytest.mark.integration
def test_the_service_logs_the_transport_s_source_never_the_claimed_one(tmp_path: Path) -> None:
    key_file = tmp_path / "rig.key"
    write_signing_key(key_file)
    lines: list[str] = []
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with OrchestratorService(endpoint, key_file=key_file, sessions_dir=tmp_path, say=lines.append):
        peer = zenoh.open(session_config(connect=[endpoint]))  # any local process, without the key
        try:
            key = ServiceKeys.for_rig().commands["pause"]
            deadline = time.monotonic() + 10
            while not peer.declare_querier(key).matching_status.matching:
                assert time.monotonic() < deadline
                time.sleep(0.02)
            replies = list(peer.get(key, payload=encode_request("pause", {"source": FORGED}), timeout=5))
            assert not decode_reply(replies[0].ok.payload.to_bytes())["ok"]  # nothing runs
        finally:
            peer.close()
        with ServiceClient(endpoint, key_file) as client, pytest.raises(Exception, match="no session"):
            client.pause(source="console browser session 7, unlocked 09:00:00Z from 127.0.0.1 (X)\ninjected")
    controls = [line for line in lines if " control pause from " in line]
    assert len(controls) == 2 and all("\n" not in line for line in controls)
    assert " control pause from unsigned zenoh client: refused" in controls[0]
    assert "Firefox" not in controls[0] and "estop" not in controls[0]
    assert (" control pause from console browser session 7, unlocked 09:00:00Z from 127.0.0.1 (X)\\x0ainjected "
            "(signed: rig key holder ") in controls[1]


# ----- 22.4: faults under their run; the operator answered from elsewhere ------------------------------------------


def test_a_fault_stays_with_the_run_it_happened_in() -> None:
    state = ConsoleState()
    header = {"plan_index": 0, "record": "r", "commanded": {"t": [], "a": []}}
    state.on_live({"session": "a.h5", "header": header})
    message = state.on_live({"session": "a.h5", "faults": [{"t": 1.0, "name": "UNDERRUN", "detail": "x"}]})
    assert message["faults"][0]["plan_index"] == 0
    state.on_live({"session": "a.h5", "header": {**header, "plan_index": 1},
                   "faults": [{"t": 0.5, "name": "LAG", "detail": "y", "plan_index": 1}]})
    assert [(f["name"], f["plan_index"]) for f in state.hello(False)["faults"]] == [("UNDERRUN", 0), ("LAG", 1)]
    state.on_live({"session": "b.h5", "header": header})  # another session: its own faults only
    assert state.hello(False)["faults"] == []


def answered(operator: RemoteOperator, ask: Any) -> tuple[threading.Thread, list[Any]]:
    """``ask()`` in a thread (the orchestrator's), once its prompt is up; its result or exception in the list."""
    out: list[Any] = []

    def run() -> None:
        try:
            out.append(ask())
        except Exception as exc:
            out.append(exc)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 10
    while operator.prompt is None:
        assert time.monotonic() < deadline and thread.is_alive()
        time.sleep(0.005)
    return thread, out


def test_the_remote_operator_waits_for_the_answer_to_its_own_prompt() -> None:
    changes: list[Any] = []
    operator = RemoteOperator(on_change=lambda: changes.append(operator.prompt))
    thread, out = answered(operator, lambda: operator.place_bodies("place the bodies at 4°"))
    prompt = operator.prompt
    assert prompt is not None and prompt["kind"] == "place_bodies" and prompt["text"] == "place the bodies at 4°"
    with pytest.raises(AnswerRefusedError, match="not the one waiting"):
        operator.answer(prompt["id"] + 1, "done")
    with pytest.raises(AnswerRefusedError, match="reply must be"):
        operator.answer(prompt["id"], "yes")
    with pytest.raises(AnswerRefusedError, match="only an answer to 'which_fell'"):
        operator.answer(prompt["id"], "done", [[1, 1]])
    assert thread.is_alive()  # still waiting
    operator.answer(prompt["id"], "done")
    thread.join(5)
    assert out == [None] and operator.prompt is None and changes[-1] is None

    run, body = SimpleNamespace(plan_index=0), SimpleNamespace(body_id=2, name="B")  # what the operator reads
    thread, out = answered(operator, lambda: operator.which_fell(run, (body,)))  # type: ignore[arg-type]
    number = operator.prompt["id"]
    assert operator.prompt["bodies"] == [{"body_id": 2, "name": "B"}]
    for bad in ([[3, 1]], [[2, 0]], [[2, 1], [2, -1]], "2", [["2", 1]]):
        with pytest.raises(AnswerRefusedError):
            operator.answer(number, "done", bad)
    operator.answer(number, "done", [[2, -1]])
    thread.join(5)
    assert out == [[(2, -1)]]

    thread, out = answered(operator, lambda: operator.place_bodies("again"))
    operator.answer(operator.prompt["id"], "decline")
    thread.join(5)
    assert isinstance(out[0], OperatorDeclinedError)

    thread, out = answered(operator, lambda: operator.place_bodies("and again"))
    operator.cancel()  # an abort: the wait ends, the orchestrator's stop check takes over
    thread.join(5)
    assert out == [None]
    with pytest.raises(AnswerRefusedError, match="no prompt"):
        operator.answer(1, "done")
