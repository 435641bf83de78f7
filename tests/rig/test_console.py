"""The operator console's server without a browser: the operator token against an HMAC written out from RFC 2104,
the controls' checks (token, same origin, host, JSON body, read-only), the WebSocket feed, the bounded per-browser
queues, the console's picture of the run, the orchestrator's live tap and the service's live publication over a
real zenoh session."""

from __future__ import annotations

import hashlib
import json
import secrets
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zenoh
from starlette.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from protocols.zenoh import session_config
from protocols.zenoh.payloads import Kind, decode_json, encode_json
from rig.console import Console, create_app, operator_token, token_from_key_file
from rig.console.hub import Hub
from rig.console.server import allowed_hosts, parse_http
from rig.console.state import WINDOW_S, ConsoleState
from rig.orchestrator.live import LiveTap, block_means
from rig.service import ServiceKeys
from rig.service.telemetry import LivePublisher, live_key
from tests.helpers.console import HOST, SAME, RecordingControls
from tests.helpers.processes import free_port


def hmac_by_hand(key: bytes, message: bytes) -> str:
    """HMAC-SHA256 from its definition (RFC 2104), not from the hmac module."""
    block = key.ljust(64, b"\0")
    inner = hashlib.sha256(bytes(b ^ 0x36 for b in block) + message).digest()
    return hashlib.sha256(bytes(b ^ 0x5C for b in block) + inner).hexdigest()



@pytest.fixture
def key() -> bytes:
    return secrets.token_bytes(32)


def console_client(token: str | None, controls: RecordingControls) -> tuple[Console, TestClient]:
    console = Console(controls, token, allowed_hosts={HOST})
    return console, TestClient(create_app(console), base_url=f"http://{HOST}")


def test_the_operator_token_is_the_rfc_2104_hmac_of_the_rig_key(key: bytes, tmp_path: Path) -> None:
    token = operator_token(key)
    assert token == hmac_by_hand(key, b"operator-console")
    assert token != operator_token(secrets.token_bytes(32))
    key_file = tmp_path / "rig.key"
    key_file.write_text(key.hex() + "\n")
    key_file.chmod(0o600)
    assert token_from_key_file(key_file) == token


def test_controls_need_the_token_a_json_body_and_the_same_origin(key: bytes) -> None:
    controls = RecordingControls()
    token = operator_token(key)
    _, client = console_client(token, controls)
    with client:
        assert client.post("/api/control/pause", headers=SAME).status_code == 403  # no token
        wrong = client.post("/api/control/pause", headers={**SAME, "X-Operator-Token": operator_token(b"x" * 32)})
        assert wrong.status_code == 403 and "token" in wrong.json()["message"]
        foreign = client.post("/api/control/estop", headers={**SAME, "Origin": "http://evil.example",
                                                             "X-Operator-Token": token})
        assert foreign.status_code == 403 and "cross-origin" in foreign.json()["message"]
        rebound = client.post("/api/control/estop", headers={**SAME, "Host": "evil.example:8080",
                                                             "Origin": "http://evil.example:8080",
                                                             "X-Operator-Token": token})
        assert rebound.status_code == 403 and "host" in rebound.json()["message"]
        site = client.post("/api/control/abort", headers={**SAME, "Sec-Fetch-Site": "cross-site",
                                                          "X-Operator-Token": token})
        assert site.status_code == 403
        form = client.post("/api/control/pause", headers={**SAME, "Content-Type": "text/plain",
                                                          "X-Operator-Token": token})
        assert form.status_code == 415
        assert controls.calls == []  # nothing refused reached the rig
        assert client.post("/api/control/launch", headers={**SAME, "X-Operator-Token": token}).status_code == 404
        for command in ("pause", "resume", "abort", "estop"):
            ok = client.post(f"/api/control/{command}", headers={**SAME, "X-Operator-Token": token})
            assert ok.status_code == 200 and ok.json() == {"ok": True, "message": f"{command} requested",
                                                           "state": "running"}
        assert [c for c, _ in controls.calls] == ["pause", "resume", "abort", "estop"]
        assert all(source.startswith("operator token from testclient") for _, source in controls.calls)
        assert client.post("/api/token", headers={**SAME, "X-Operator-Token": token}).json()["ok"]
        # no CORS: a foreign page's preflight gets no Access-Control-Allow-Origin
        preflight = client.options("/api/control/pause", headers={"Origin": "http://evil.example",
                                                                  "Access-Control-Request-Method": "POST"})
        assert "access-control-allow-origin" not in preflight.headers


def test_a_refusal_by_the_service_is_passed_on(key: bytes) -> None:
    controls = RecordingControls(refuse=("resume",))
    _, client = console_client(operator_token(key), controls)
    with client:
        reply = client.post("/api/control/resume", headers={**SAME, "X-Operator-Token": operator_token(key)})
    assert reply.status_code == 409 and reply.json()["message"] == "cannot resume: no session is running"


def test_without_a_rig_key_the_console_is_read_only() -> None:
    controls = RecordingControls()
    _, client = console_client(None, controls)
    with client:
        refused = client.post("/api/control/estop", headers={**SAME, "X-Operator-Token": "anything"})
        assert refused.status_code == 403 and "read-only" in refused.json()["message"]
        assert client.get("/api/state").json()["controls"] is False
    assert controls.calls == []


def test_the_page_and_the_vendored_uplot_are_served(key: bytes) -> None:
    _, client = console_client(operator_token(key), RecordingControls())
    with client:
        page = client.get("/")
        assert page.status_code == 200 and "/static/vendor/uplot/uPlot.iife.min.js" in page.text
        assert 'id="estop"' in page.text
        script = client.get("/static/vendor/uplot/uPlot.iife.min.js")
        assert script.status_code == 200 and "uPlot" in script.text
        assert client.get("/static/console.js").status_code == 200
        assert "MIT" in client.get("/static/vendor/uplot/LICENSE").text
        assert client.get("/report").status_code == 404  # no finished session yet


def test_the_websocket_says_hello_then_passes_the_telemetry_on(key: bytes) -> None:
    console, client = console_client(operator_token(key), RecordingControls())
    with client, client.websocket_connect(f"ws://{HOST}/ws", headers={"Origin": f"http://{HOST}"}) as ws:
        hello = ws.receive_json()
        assert hello["type"] == "hello" and hello["controls"] is True and hello["status"] is None
        client.portal.call(console.deliver, "status", {"state": "running", "t_ns": 1, "seq": 1})
        assert ws.receive_json() == {"type": "status", "state": "running", "t_ns": 1, "seq": 1}
        frame = {"state": "live", "session": "s.h5", "accel": {"t": [0.0, 0.02], "a": [0.1, 0.2]},
                 "pose": {"t": [], "p": []}, "detections": [{"t": 0.02, "body_id": 1, "direction": 1}], "faults": []}
        client.portal.call(console.deliver, "live", frame)
        assert ws.receive_json() == {"type": "live", **frame}
    assert console.state.detections == frame["detections"]


def test_a_websocket_from_another_origin_is_refused(key: bytes) -> None:
    _, client = console_client(operator_token(key), RecordingControls())
    with client, pytest.raises(WebSocketDisconnect) as refused, \
            client.websocket_connect(f"ws://{HOST}/ws", headers={"Origin": "http://evil.example"}) as ws:
        ws.receive_json()
    assert refused.value.code == 1008


def test_a_slow_browser_loses_frames_and_they_are_counted() -> None:
    hub = Hub(capacity=4)
    slow, quick = hub.connect("slow"), hub.connect("quick")
    for n in range(10):
        hub.publish(json.dumps({"n": n}))
        if not quick.queue.empty():
            quick.queue.get_nowait()  # the quick browser takes each message at once
    assert (slow.queued, slow.dropped) == (4, 6)
    assert (quick.queued, quick.dropped) == (10, 0)
    hub.publish(json.dumps({"status": "paused"}), droppable=False)  # a status is never the one dropped
    assert slow.dropped == 7 and slow.queue.qsize() == 4
    assert [json.loads(slow.queue.get_nowait()) for _ in range(4)][-1] == {"status": "paused"}
    hub.disconnect(slow)
    hub.publish("{}")
    assert slow.dropped == 7 and hub.stats()["published"] == 12


def test_the_console_keeps_the_last_window_and_starts_afresh_on_a_new_run() -> None:
    state = ConsoleState()
    header = {"plan_index": 0, "record": "r", "commanded": {"t": [], "a": []}}
    t = np.arange(0, 30, 0.02)
    state.on_live({"session": "a.h5", "header": header, "accel": {"t": t.tolist(), "a": t.tolist()}})
    kept = [s for s, _ in state.accel]
    assert kept[-1] == pytest.approx(t[-1]) and kept[-1] - kept[0] <= WINDOW_S
    assert kept[-1] - kept[0] > WINDOW_S - 0.1
    state.on_live({"session": "a.h5", "detections": [{"t": 1.0, "body_id": 1, "direction": -1}]})
    assert len(state.detections) == 1
    state.on_live({"session": "a.h5", "header": {**header, "plan_index": 1}, "accel": {"t": [0.0], "a": [1.0]}})
    assert state.detections == [] and list(state.accel) == [(0.0, 1.0)]
    assert state.hello(False)["header"]["plan_index"] == 1


def test_the_live_tap_decimates_across_batches_and_stays_bounded() -> None:
    rate = 1000.0
    t = np.arange(2000) / rate
    a = np.sin(2 * np.pi * 3 * t) + 0.01 * np.arange(2000)
    tap = LiveTap(capacity=1000)
    for start in range(0, 2000, 7):  # batches of 7 samples: blocks of 20 span several batches
        tap.accel(0, t[start:start + 7], a[start:start + 7])
    items = tap.drain()
    got_t = np.concatenate([item[1] for item in items])
    got_a = np.concatenate([item[2] for item in items])
    assert np.allclose(got_a, a.reshape(-1, 20).mean(axis=1)) and np.allclose(got_t, t.reshape(-1, 20).mean(axis=1))
    for n in range(1500):
        tap.put("pose", [n], [[0.0] * 6])
    kept = tap.drain()
    assert len(kept) == 1000 and kept[0][1] == [500] and tap.drain() == []
    bt, ba = block_means(t[:45], a[:45], rate)
    assert len(bt) == 3 and ba[2] == pytest.approx(a[40:45].mean())


def published_frames(keys: ServiceKeys, tap: LiveTap, enough: int) -> list[dict[str, Any]]:
    """The live frames a :class:`LivePublisher` of ``tap`` sends to a subscriber in another zenoh session on
    loopback (the subscription made sure to reach the publisher first, by a probe), until ``enough`` arrived or 30 s
    passed."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    publisher_session = zenoh.open(session_config(listen=[endpoint]))
    subscriber_session = zenoh.open(session_config(connect=[endpoint]))
    frames: list[dict[str, Any]] = []
    try:
        subscriber = subscriber_session.declare_subscriber(
            live_key(keys), lambda sample: frames.append(decode_json(sample.payload.to_bytes(), Kind.STATUS)))
        probe = publisher_session.declare_publisher(live_key(keys))
        deadline = time.monotonic() + 30
        while not frames and time.monotonic() < deadline:
            probe.put(encode_json(Kind.STATUS, {"state": "probe", "t_ns": 0, "seq": 0, "pose": {"t": []}}))
            time.sleep(0.05)
        probe.undeclare()
        time.sleep(0.2)
        frames.clear()
        publisher = LivePublisher(publisher_session, keys, lambda: ("s.h5", tap, None))
        try:
            deadline = time.monotonic() + 30
            while len(frames) < enough and time.monotonic() < deadline:
                time.sleep(0.05)
        finally:
            publisher.close()
            subscriber.undeclare()
    finally:
        publisher_session.close()
        subscriber_session.close()
    return frames


@pytest.mark.integration
def test_the_service_publishes_the_live_tap_on_zenoh() -> None:
    tap = LiveTap()
    tap.begin_run({"plan_index": 0, "record": "r", "commanded": {"t": [0.0], "a": [0.5]}})
    tap.put("detection", float("nan"), 2, -1)  # an operator's detection has no time: null in JSON
    frames = published_frames(ServiceKeys.for_rig("consoletest"), tap, 1)
    assert frames, "no live frame arrived"
    first = frames[0]
    assert first["session"] == "s.h5" and first["header"]["record"] == "r"
    assert first["detections"] == [{"t": None, "body_id": 2, "direction": -1}]


@pytest.mark.integration
def test_a_run_s_tail_and_the_next_run_never_share_a_live_frame() -> None:
    """The tap drained at once holds run 1's last poses, run 2's header and its first poses: they go out as two
    frames, so that a page clearing its plots at run 2's header does not show run 1's tail as run 2's (the console
    test saw run 1's 6 s in run 2's plot)."""
    tap = LiveTap()
    tap.begin_run({"plan_index": 0, "record": "r1", "commanded": {"t": [0.0], "a": [0.0]}})
    tap.put("pose", [6.0, 6.3], [[0.0] * 6, [0.0] * 6])
    tap.begin_run({"plan_index": 1, "record": "r2", "commanded": {"t": [0.0], "a": [0.0]}})
    tap.put("pose", [-0.05, 0.0], [[0.0] * 6, [0.0] * 6])
    frames = published_frames(ServiceKeys.for_rig("consoletest2"), tap, 3)
    runs = [(f.get("header", {}).get("plan_index"), f["pose"]["t"]) for f in frames if f["pose"]["t"]]
    assert runs == [(0, [6.0, 6.3]), (1, [-0.05, 0.0])], frames


def test_http_addresses_and_the_hosts_they_accept() -> None:
    assert parse_http("127.0.0.1:8080") == ("127.0.0.1", 8080)
    assert parse_http("[::1]:9000") == ("::1", 9000)
    with pytest.raises(Exception, match="HOST:PORT"):
        parse_http("8080")
    assert allowed_hosts("127.0.0.1", 8080) == {"127.0.0.1:8080", "localhost:8080", "[::1]:8080"}
    assert allowed_hosts("192.0.2.7", 80) == {"192.0.2.7:80", "192.0.2.7"}  # a browser omits the default port
    assert allowed_hosts("10.0.0.5", 8443, ("rig.lab",)) == {"10.0.0.5:8443", "rig.lab:8443"}
