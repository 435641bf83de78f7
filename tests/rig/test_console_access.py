"""Who may use the console (issue 37 item 2), in process with starlette's TestClient: the tokens file's operators and
viewers, a viewer's control refused and logged, a token revoked by editing the file without a restart, the source of
a control from the transport and not from the request, the tokens file's bad input, a token past its expiry refused
and logged, and the HTTPS certificate given or made on first use; one test serves the page over real HTTPS
(integration)."""

from __future__ import annotations

import os
import secrets
import ssl
import threading
import time
import urllib.error
import urllib.request
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
from starlette.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from rig.certs import fingerprint, make_identity
from rig.console import Console, create_app, operator_token
from rig.console.access import AccessError, TokensFile, read_tokens
from rig.console.https import HttpsError, https_files
from rig.console.server import console_server
from tests.helpers.console import RecordingControls

HOST = "10.231.0.1:8443"
SAME = {"Host": HOST, "Origin": f"https://{HOST}", "Content-Type": "application/json"}



def write_tokens(path: Path, entries: list[tuple[str, str, str]]) -> None:
    """The tokens file ``path`` (mode 0600) holding (name, role, token) entries; its modification time moved on so
    that a rewrite within the file system's time resolution is seen as a change too."""
    text = "".join(f'[[token]]\nname = "{n}"\nrole = "{r}"\ntoken = "{t}"\n\n' for n, r, t in entries)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as file:
        file.write(text)
    later = time.time_ns() + 2_000_000_000 * len(entries) + 1
    os.utime(path, ns=(later, later))


@pytest.fixture
def lab(tmp_path: Path) -> dict[str, Any]:
    operator, viewer = secrets.token_urlsafe(32), secrets.token_urlsafe(32)
    path = tmp_path / "tokens.toml"
    write_tokens(path, [("control-room", "operator", operator), ("tablet", "viewer", viewer)])
    said: list[str] = []
    controls = RecordingControls()
    console = Console(controls, operator_token(secrets.token_bytes(32)), allowed_hosts={HOST},
                      tokens=TokensFile(path, said.append), say=said.append)
    client = TestClient(create_app(console), base_url=f"https://{HOST}")
    return {"path": path, "operator": operator, "viewer": viewer, "said": said, "controls": controls,
            "client": client}


def unlock(client: TestClient, token: str) -> dict[str, Any]:
    reply = client.post("/api/token", headers={**SAME, "X-Operator-Token": token})
    assert reply.status_code == 200, reply.text
    return reply.json()


def test_a_viewer_watches_and_its_command_is_refused_and_logged(lab: dict[str, Any]) -> None:
    client, controls = lab["client"], lab["controls"]
    with client:
        opened = unlock(client, lab["viewer"])
        assert opened["role"] == "viewer" and "may watch, not command" in opened["message"]
        assert client.get("/api/state", headers=SAME).status_code == 200
        with client.websocket_connect(f"wss://{HOST}/ws", headers={"Host": HOST, "Origin": f"https://{HOST}"}) as ws:
            assert ws.receive_json()["type"] == "hello"
        refused = client.post("/api/control/pause", headers={**SAME, "X-Console-CSRF": opened["csrf"]})
        assert refused.status_code == 403 and "'tablet' is a viewer" in refused.json()["message"]
        by_header = client.post("/api/control/estop", headers={**SAME, "X-Operator-Token": lab["viewer"]})
        assert by_header.status_code == 403
    assert controls.calls == []
    refusals = [line for line in lab["said"] if line.startswith("control ")]
    assert len(refusals) == 2 and "refused (a viewer may watch only)" in refusals[0]
    assert "'tablet'" in refusals[0] and "control estop" in refusals[1]
    # passed on to the service, to be logged in the session's events with who was refused
    assert [(command, reason) for command, _, reason in controls.refusals] == [
        ("pause", "a viewer may watch only"), ("estop", "a viewer may watch only")]
    assert all("'tablet'" in source for _, source, _ in controls.refusals), controls.refusals


def test_with_a_tokens_file_nothing_is_shown_without_a_token(lab: dict[str, Any]) -> None:
    client = lab["client"]
    with client:
        assert client.get("/", headers={"Host": HOST}).status_code == 200  # the page, to type the token in
        state = client.get("/api/state", headers={"Host": HOST})
        assert state.status_code == 403 and "token holders only" in state.json()["message"]
        assert client.get("/report", headers={"Host": HOST}).status_code == 403
        with pytest.raises(WebSocketDisconnect), \
                client.websocket_connect(f"wss://{HOST}/ws", headers={"Host": HOST, "Origin": f"https://{HOST}"}) as ws:
            ws.receive_json()
        wrong = client.post("/api/token", headers={**SAME, "X-Operator-Token": secrets.token_urlsafe(32)})
        assert wrong.status_code == 403


def test_an_operator_commands_named_by_the_transport_not_the_request(lab: dict[str, Any]) -> None:
    client, controls = lab["client"], lab["controls"]
    with client:
        opened = unlock(client, lab["operator"])
        assert opened["role"] == "operator"
        forged = '{"source": "estop from the rig key holder", "who": "someone else"}'
        ok = client.post("/api/control/pause", headers={**SAME, "X-Console-CSRF": opened["csrf"]}, content=forged)
        assert ok.status_code == 200, ok.text
        client.cookies.clear()
        ok = client.post("/api/control/resume", headers={**SAME, "X-Operator-Token": lab["operator"]}, content=forged)
        assert ok.status_code == 200, ok.text
    (pause, by_session), (resume, by_token) = controls.calls
    assert pause == "pause" and by_session.startswith("console browser session 1, unlocked ")
    assert " from testclient " in by_session and by_session.endswith("with the operator token of 'control-room'")
    assert resume == "resume" and by_token.startswith("operator token from testclient")
    assert by_token.endswith("held by 'control-room'")
    assert not any("someone else" in source or "rig key holder" in source for _, source in controls.calls)


def test_a_token_revoked_in_the_file_is_refused_at_once_without_a_restart(lab: dict[str, Any]) -> None:
    client, controls = lab["client"], lab["controls"]
    with client:
        opened = unlock(client, lab["operator"])
        assert client.post("/api/control/pause", headers={**SAME, "X-Console-CSRF": opened["csrf"]}).status_code == 200
        write_tokens(lab["path"], [("tablet", "viewer", lab["viewer"])])  # control-room revoked
        after = client.post("/api/control/abort", headers={**SAME, "X-Console-CSRF": opened["csrf"]})
        assert after.status_code == 403
        assert client.get("/api/session", headers={"Host": HOST}).json() == {"unlocked": False}
        assert client.post("/api/control/abort", headers={**SAME, "X-Operator-Token": lab["operator"]}).status_code \
            == 403
        demoted = secrets.token_urlsafe(32)
        write_tokens(lab["path"], [("tablet", "viewer", lab["viewer"]), ("new", "operator", demoted)])
        assert client.post("/api/control/abort", headers={**SAME, "X-Operator-Token": demoted}).status_code == 200
    assert [command for command, _ in controls.calls] == ["pause", "abort"]
    assert any("ended: its token was revoked" in line for line in lab["said"])
    assert any("read again: 1 tokens" in line for line in lab["said"])


def test_a_tokens_file_broken_while_serving_grants_nothing(lab: dict[str, Any]) -> None:
    lab["path"].write_text("[[token]\nname = ")
    with lab["client"] as client:
        assert client.post("/api/token", headers={**SAME, "X-Operator-Token": lab["operator"]}).status_code == 403
    assert any("no token of the file is accepted until it is fixed" in line for line in lab["said"])


def test_an_expired_token_is_refused_with_a_clear_message_and_logged(tmp_path: Path) -> None:
    now = [datetime(2026, 12, 6, 9, 0, tzinfo=UTC)]
    stale, shift = secrets.token_urlsafe(32), secrets.token_urlsafe(32)
    path = tmp_path / "tokens.toml"
    path.write_text(f'[[token]]\nname = "last-week"\nrole = "operator"\ntoken = "{stale}"\n'
                    f'expires = 2026-12-01T18:00:00+01:00\n\n'
                    f'[[token]]\nname = "day-shift"\nrole = "operator"\ntoken = "{shift}"\n'
                    f'expires = 2026-12-06T17:00:00Z\n')
    path.chmod(0o600)
    said: list[str] = []
    controls = RecordingControls()
    console = Console(controls, None, allowed_hosts={HOST}, say=said.append,
                      tokens=TokensFile(path, said.append, clock=lambda: now[0]))
    with TestClient(create_app(console), base_url=f"https://{HOST}") as client:
        for _ in range(2):
            refused = client.post("/api/token", headers={**SAME, "X-Operator-Token": stale})
            assert refused.status_code == 403
            assert refused.json()["message"] == ("refused: the token of 'last-week' expired at 2026-12-01T17:00:00Z: "
                                                 "ask the operator for a new one (the tokens file's expires)")
        by_header = client.post("/api/control/pause", headers={**SAME, "X-Operator-Token": stale})
        assert by_header.status_code == 403 and "'last-week' expired at" in by_header.json()["message"]
        watching = client.get("/api/state", headers={"Host": HOST, "X-Operator-Token": stale})
        assert watching.status_code == 403 and "expired at" in watching.json()["message"]
        opened = unlock(client, shift)  # before its expiry: a browser session, and its controls
        assert client.post("/api/control/pause", headers={**SAME, "X-Console-CSRF": opened["csrf"]}).status_code == 200
        now[0] = datetime(2026, 12, 6, 17, 0, tzinfo=UTC)  # the day shift's token expires: its session ends
        after = client.post("/api/control/resume", headers={**SAME, "X-Console-CSRF": opened["csrf"]})
        assert after.status_code == 403
        again = client.post("/api/control/resume", headers={**SAME, "X-Operator-Token": shift})
        assert again.status_code == 403 and "'day-shift' expired at 2026-12-06T17:00:00Z" in again.json()["message"]
    assert [command for command, _ in controls.calls] == ["pause"]
    expiries = [line for line in said if "refused: it expired" in line]
    assert expiries == ["token of 'last-week' refused: it expired at 2026-12-01T17:00:00Z",
                        "token of 'day-shift' refused: it expired at 2026-12-06T17:00:00Z"]  # each logged once
    assert any("of 'day-shift' ended: its token expired" in line for line in said)


@pytest.mark.parametrize(("text", "mode", "expected"), [
    ('[[token]]\nname = "a"\nrole = "operator"\ntoken = "' + "x" * 40 + '"\n', 0o644, "mode 0644 .* chmod 600"),
    ('[[token]]\nname = "a"\nrole = "operator"\ntoken = "short"\n', 0o600,
     r"\[\[token\]\] #1 \(a\): token: expected at least 32 characters"),
    ('[[token]]\nname = "a"\nrole = "admin"\ntoken = "' + "x" * 40 + '"\n', 0o600,
     r"#1 \(a\): role 'admin': expected one of operator, viewer"),
    ('[[token]]\nname = "a"\nrole = "viewer"\ntoken = "' + "x" * 40 + '"\nexpires = 3\n', 0o600,
     r"#1 \(a\): expires 3: expected a date-time with its offset"),
    ('[[token]]\nname = "a"\nrole = "viewer"\ntoken = "' + "x" * 40 + '"\nexpires = 2026-12-31T18:00:00\n', 0o600,
     r"#1 \(a\): expires .*: expected a date-time with its offset, e.g. expires = 2026-12-31T18:00:00Z"),
    ('[[token]]\nname = "a"\nrole = "viewer"\ntoken = "' + "x" * 40 + '"\nvalid = 3\n', 0o600,
     "unknown field 'valid'; expected name, role, token, expires"),
    ('[[token]]\nname = "a"\nrole = "viewer"\n\ntoken = = 1\n', 0o600, r"at line 5, column 9"),
    ('[[token]]\nname = "rig key"\nrole = "viewer"\ntoken = "' + "x" * 40 + '"\n', 0o600, "name 'rig key'"),
])
def test_a_bad_tokens_file_is_refused_with_where_and_what(tmp_path: Path, text: str, mode: int,
                                                          expected: str) -> None:
    path = tmp_path / "tokens.toml"
    path.write_text(text)
    path.chmod(mode)
    with pytest.raises(AccessError, match=expected) as raised:
        read_tokens(path)
    assert str(path) in str(raised.value) and "\n" not in str(raised.value)


def test_the_https_certificate_given_or_made_on_first_use(tmp_path: Path) -> None:
    said: list[str] = []
    made = https_files("10.231.0.1", ("rig.lab",), certificate=None, key=None, directory=tmp_path / "web",
                       say=said.append)
    assert made is not None and made.certificate == tmp_path / "web" / "console.pem"
    printed = fingerprint(made.certificate)
    assert any(printed in line for line in said) and any("made the console's certificate" in line for line in said)
    again = https_files("10.231.0.1", (), certificate=None, key=None, directory=tmp_path / "web", say=said.append)
    assert again == made and fingerprint(made.certificate) == printed  # reused, not made again
    lab = make_identity(tmp_path / "certs", "console", addresses=("10.231.0.1",))
    assert https_files("10.231.0.1", (), certificate=lab.certificate, key=lab.key, directory=None,
                       say=said.append) == (lab.certificate, lab.key)
    with pytest.raises(HttpsError, match="not the key of the certificate"):
        https_files("10.231.0.1", (), certificate=lab.certificate, key=made.key, directory=None, say=said.append)
    with pytest.raises(HttpsError, match="--https-cert without --https-key"):
        https_files("10.231.0.1", (), certificate=lab.certificate, key=None, directory=None, say=said.append)
    (tmp_path / "bad.pem").write_text("not a certificate")
    with pytest.raises(HttpsError, match=r"--https-cert .*bad.pem: not a PEM certificate"):
        https_files("10.231.0.1", (), certificate=tmp_path / "bad.pem", key=lab.key, directory=None, say=said.append)
    with pytest.raises(HttpsError, match="not on loopback: serve HTTPS"):
        https_files("10.231.0.1", (), certificate=None, key=None, directory=None, say=said.append)
    assert https_files("127.0.0.1", (), certificate=None, key=None, directory=None, say=said.append) is None


def test_an_http_origin_is_foreign_to_an_https_console(lab: dict[str, Any]) -> None:
    with lab["client"] as client:
        plain = client.post("/api/token", headers={**SAME, "Origin": f"http://{HOST}",
                                                   "X-Operator-Token": lab["operator"]})
        assert plain.status_code == 403 and "cross-origin" in plain.json()["message"]


@pytest.mark.integration  # serves on a socket
def test_the_console_serves_the_page_over_https(tmp_path: Path) -> None:
    files = https_files("127.0.0.1", (), certificate=None, key=None, directory=tmp_path, say=lambda line: None)
    assert files is not None
    server = console_server(Console(None, None), "127.0.0.1", 0, https=files)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        while not server.started:
            assert thread.is_alive(), "the console did not start"
            time.sleep(0.05)
        port = server.servers[0].sockets[0].getsockname()[1]
        trusting = ssl.create_default_context(cafile=str(tmp_path / "ca.pem"))
        with urllib.request.urlopen(f"https://127.0.0.1:{port}/", context=trusting, timeout=30) as page:
            assert page.status == 200 and b"<html" in page.read().lower()
        with pytest.raises(urllib.error.URLError, match="CERTIFICATE_VERIFY_FAILED"):
            urllib.request.urlopen(f"https://127.0.0.1:{port}/", context=ssl.create_default_context(), timeout=30)
    finally:
        server.should_exit = True
        thread.join(30)
