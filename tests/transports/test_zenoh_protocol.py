"""zenoh wire formats of the rig service: key expressions, versioned payloads, the session configuration, then two
real zenoh sessions in this process (one listening on a loopback port, one connecting; no scouting)."""

from __future__ import annotations

import json
import queue
import socket
import struct
import threading
from collections.abc import Iterator

import numpy as np
import pytest
import zenoh
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from protocols.zenoh import (
    MAGIC,
    SERVICE_COMMANDS,
    TELEMETRY_PAYLOADS,
    EndpointError,
    Key,
    KeyExprError,
    Kind,
    PayloadError,
    alive_key,
    alive_selector,
    check_endpoint,
    decode_accel,
    decode_json,
    encode_accel,
    encode_json,
    loopback_endpoint,
    parse_key,
    read_header,
    service_key,
    service_selector,
    session_config,
    telemetry_key,
    telemetry_selector,
)
from protocols.zenoh.config import TX_QUEUE_BATCHES

pytestmark = pytest.mark.integration  # starts processes or opens sockets (tests/conftest.py)

RIG = "lab-a"
WAIT = 5.0
"""Upper bound [s] on waiting for something that must happen (never reached when zenoh works)."""

# ----- keys ---------------------------------------------------------------------------------------------------


def test_keys() -> None:
    assert [service_key(RIG, c) for c in SERVICE_COMMANDS] == [
        f"shaketable/lab-a/service/{c}" for c in ("start", "pause", "resume", "abort", "estop", "state", "queue",
                                                      "answer")]
    assert telemetry_key(RIG, "status") == "shaketable/lab-a/telemetry/status"
    assert telemetry_key(RIG, "accel", "plate_1") == "shaketable/lab-a/telemetry/accel/plate_1"
    assert telemetry_key(RIG, "detection") == "shaketable/lab-a/telemetry/detection"
    assert telemetry_key(RIG, "run") == "shaketable/lab-a/telemetry/run"
    assert alive_key(RIG, "service") == "shaketable/lab-a/alive/service"
    assert service_selector(RIG) == "shaketable/lab-a/service/*"
    assert telemetry_selector(RIG) == "shaketable/lab-a/telemetry/**"
    assert alive_selector() == "shaketable/*/alive/*" and alive_selector(RIG) == "shaketable/lab-a/alive/*"


def test_selectors_match_their_keys_in_zenoh() -> None:
    """Each selector includes its keys and nothing of the other planes (zenoh's own key expression algebra)."""
    service, telemetry, alive = (zenoh.KeyExpr(s) for s in (service_selector(RIG), telemetry_selector(RIG),
                                                             alive_selector()))
    assert all(service.includes(service_key(RIG, c)) for c in SERVICE_COMMANDS)
    assert telemetry.includes(telemetry_key(RIG, "accel", "s1")) and telemetry.includes(telemetry_key(RIG, "run"))
    assert alive.includes(alive_key("other-rig", "emulator"))
    assert not service.intersects(telemetry_key(RIG, "status"))
    assert not telemetry.intersects(service_key(RIG, "start"))
    assert not zenoh.KeyExpr(service_selector("lab-b")).intersects(service_key(RIG, "start"))


@pytest.mark.parametrize("key", [
    service_key(RIG, "estop"), telemetry_key(RIG, "accel", "s-2"), telemetry_key(RIG, "status"),
    alive_key(RIG, "emulator")])
def test_parse_key_round_trips(key: str) -> None:
    parsed = parse_key(key)
    assert parsed.rig == RIG
    rebuilt = {"service": lambda k: service_key(k.rig, k.name),
               "telemetry": lambda k: telemetry_key(k.rig, k.name, k.sensor),
               "alive": lambda k: alive_key(k.rig, k.name)}[parsed.plane](parsed)
    assert rebuilt == key
    assert parse_key(zenoh.KeyExpr(key)) == parsed


def test_parse_key_parts() -> None:
    assert parse_key("shaketable/r1/telemetry/accel/plate") == Key("r1", "telemetry", "accel", "plate")
    assert parse_key("shaketable/r1/service/start") == Key("r1", "service", "start", None)


@pytest.mark.parametrize(("call", "message"), [
    (lambda: service_key("Lab A", "start"),
     r"rig name 'Lab A' is not valid: use 1\.\.32 characters from a-z, 0-9, '-' and '_', starting with a letter"),
    (lambda: service_key("", "start"), r"rig name '' is not valid"),
    (lambda: service_key("a" * 33, "start"), r"rig name 'a{33}' is not valid"),
    (lambda: service_key("-lab", "start"), r"rig name '-lab' is not valid"),
    (lambda: service_key("lab/*", "start"), r"rig name 'lab/\*' is not valid"),
    (lambda: service_key(RIG, "stop"),
     r"unknown service command 'stop'; expected one of start, pause, resume, abort, estop, state"),
    (lambda: telemetry_key(RIG, "pose"), r"unknown telemetry kind 'pose'; expected one of status, accel"),
    (lambda: telemetry_key(RIG, "accel"), r"telemetry kind 'accel' needs a sensor name"),
    (lambda: telemetry_key(RIG, "status", "s1"), r"telemetry kind 'status' takes no sensor name, got 's1'"),
    (lambda: telemetry_key(RIG, "accel", "s$1"), r"sensor name 's\$1' is not valid"),
    (lambda: alive_key(RIG, "Service"), r"role 'Service' is not valid"),
    (lambda: alive_selector("*"), r"rig name '\*' is not valid"),
    (lambda: parse_key("other/lab-a/service/start"), r"is not a rig key: expected shaketable/<rig>/<plane>/<name>"),
    (lambda: parse_key("shaketable/lab-a/service"), r"is not a rig key"),
    (lambda: parse_key("shaketable/lab-a/control/start"), r"unknown plane 'control'"),
    (lambda: parse_key("shaketable/lab-a/service/start/now"), r"has 5 chunks; service/start keys have 4"),
    (lambda: parse_key("shaketable/lab-a/telemetry/accel"), r"has 4 chunks; telemetry/accel keys have 5"),
    (lambda: parse_key("shaketable/lab-a/telemetry/accel/*"), r"sensor name '\*' is not valid"),
])
def test_key_errors(call, message: str) -> None:
    with pytest.raises(KeyExprError, match=message):
        call()


# ----- payloads -----------------------------------------------------------------------------------------------

BODIES = {
    Kind.CONTROL_REQUEST: {"command": "start", "args": {"sequence": "seq.toml", "angle_deg": 5.0}},
    Kind.CONTROL_REPLY: {"ok": True, "state": "running", "message": "", "run": 3},
    Kind.STATUS: {"t_ns": 1_700_000_000_123_456_789, "state": "idle", "buffer_depth": 12, "faults": []},
    Kind.DETECTION: {"t_ns": 42, "event_id": 7, "body_id": 2, "direction": -1},
    Kind.RUN: {"run": 0, "status": "completed", "record": "suite:ff01", "scale_factor": 0.68},
}


@pytest.mark.parametrize("kind", list(BODIES), ids=lambda k: k.name)
def test_json_payloads_round_trip(kind: Kind) -> None:
    payload = encode_json(kind, BODIES[kind])
    assert payload[:8] == MAGIC + struct.pack("<HH", 1, kind)
    assert read_header(payload) is kind
    assert decode_json(payload, kind) == BODIES[kind]
    assert decode_json(bytearray(payload), kind) == BODIES[kind]


def test_json_body_is_compact_utf8() -> None:
    payload = encode_json(Kind.STATUS, {"t_ns": 1, "state": "prêt"})
    assert payload[8:] == '{"t_ns":1,"state":"prêt"}'.encode()


@given(st.integers(-(2**63), 2**63 - 1), st.integers(0, 2**31), st.sampled_from([-1, 0, 1]))
def test_detection_round_trips_any_integers(t_ns: int, body_id: int, direction: int) -> None:
    body = {"t_ns": t_ns, "event_id": body_id + 1, "body_id": body_id, "direction": direction}
    assert decode_json(encode_json(Kind.DETECTION, body), Kind.DETECTION) == body


def _with_header(body: bytes, kind: int = Kind.STATUS, version: int = 1, magic: bytes = MAGIC) -> bytes:
    return struct.pack("<4sHH", magic, version, kind) + body


@pytest.mark.parametrize(("payload", "message"), [
    (b"SHKT\x01", r"payload truncated: 5 bytes, the header alone has 8"),
    (b"", r"payload truncated: 0 bytes"),
    (_with_header(b"{}", magic=b"MAVL"), r"not a shaketable payload: magic b'MAVL', expected b'SHKT'"),
    (_with_header(b"{}", version=2), r"payload version 2 is not supported \(this reader knows version 1\)"),
    (_with_header(b"{}", version=0), r"payload version 0 is not supported"),
    (_with_header(b"{}", kind=99), r"unknown payload kind 99 \(known: 1 CONTROL_REQUEST, 2 CONTROL_REPLY"),
    (_with_header(b"{}", kind=Kind.RUN), r"expected a STATUS payload, got RUN"),
    (_with_header(b'{"t_ns": 1, "state"'), r"STATUS body is not UTF-8 JSON \(19 bytes\)"),
    (_with_header(b"\xff\xfe"), r"STATUS body is not UTF-8 JSON"),
    (_with_header(b'{"t_ns": NaN, "state": "x"}'), r"STATUS body is not UTF-8 JSON .*NaN is not JSON"),
    (_with_header(b"[1, 2]"), r"STATUS body must be a JSON object, got list"),
    (_with_header(b'{"state": "idle"}'), r"STATUS body lacks the field 't_ns'"),
    (_with_header(b'{"t_ns": 1.5, "state": "idle"}'), r"STATUS field 't_ns' must be int, got float 1\.5"),
    (_with_header(b'{"t_ns": true, "state": "idle"}'), r"STATUS field 't_ns' must be int, got bool True"),
])
def test_decode_errors(payload: bytes, message: str) -> None:
    with pytest.raises(PayloadError, match=message):
        decode_json(payload, Kind.STATUS)


@pytest.mark.parametrize(("kind", "body", "message"), [
    (Kind.CONTROL_REQUEST, {"command": "stop", "args": {}}, r"unknown command 'stop'; expected one of start"),
    (Kind.CONTROL_REQUEST, {"command": "start"}, r"CONTROL_REQUEST body lacks the field 'args'"),
    (Kind.CONTROL_REPLY, {"ok": 1, "state": "idle", "message": ""}, r"field 'ok' must be bool, got int 1"),
    (Kind.DETECTION, {"t_ns": 1, "event_id": 1, "body_id": 0, "direction": 2},
     r"DETECTION direction must be \+1, -1 or 0, got 2"),
    (Kind.STATUS, {"t_ns": 1, "state": "x", "peak": float("nan")}, r"STATUS body is not JSON-serialisable"),
    (Kind.STATUS, {"t_ns": 1, "state": "x", "when": object()}, r"STATUS body is not JSON-serialisable"),
    (Kind.STATUS, ["t_ns"], r"STATUS body must be a JSON object, got list"),
    (Kind.ACCEL, {}, r"ACCEL is not a JSON kind"),
])
def test_encode_errors(kind: Kind, body, message: str) -> None:
    with pytest.raises(PayloadError, match=message):
        encode_json(kind, body)


def test_accel_layout() -> None:
    t = np.array([10, 20], dtype=np.int64)
    acc = np.array([[0.1, -0.2, 9.81], [1.0, 2.0, 3.0]])
    payload = encode_accel(t, acc)
    assert len(payload) == 8 + 4 + 2 * 32
    assert payload[8:12] == b"\x02\x00\x00\x00"
    assert payload[12:28] == struct.pack("<qq", 10, 20)
    assert payload[28:] == struct.pack("<6d", 0.1, -0.2, 9.81, 1.0, 2.0, 3.0)
    batch = decode_accel(payload)
    assert batch.t_ns.dtype == np.int64 and batch.acc.shape == (2, 3) and batch.acc.flags.writeable
    np.testing.assert_array_equal(batch.t_ns, t)
    np.testing.assert_array_equal(batch.acc, acc)
    empty = decode_accel(encode_accel(np.zeros(0, dtype=np.int64), np.zeros((0, 3))))
    assert empty.t_ns.shape == (0,) and empty.acc.shape == (0, 3)


@given(hnp.arrays(np.int64, st.integers(0, 40)).flatmap(
    lambda t: st.tuples(st.just(t), hnp.arrays(np.float64, (len(t), 3), elements=st.floats(allow_nan=False,
                                                                                           allow_infinity=False)))))
def test_accel_round_trip(batch) -> None:
    t, acc = batch
    decoded = decode_accel(encode_accel(t, acc))
    np.testing.assert_array_equal(decoded.t_ns, t)
    np.testing.assert_array_equal(decoded.acc, acc)


def test_accel_errors() -> None:
    good = encode_accel(np.array([1, 2, 3]), np.zeros((3, 3)))
    with pytest.raises(PayloadError, match=r"ACCEL payload truncated: 3 samples need a body of 100 bytes, got 99"):
        decode_accel(good[:-1])
    with pytest.raises(PayloadError, match=r"ACCEL payload too long: 3 samples need a body of 100 bytes, got 101"):
        decode_accel(good + b"\x00")
    with pytest.raises(PayloadError, match=r"ACCEL payload truncated: body of 2 bytes has no sample count"):
        decode_accel(good[:10])
    with pytest.raises(PayloadError, match=r"expected a ACCEL payload, got STATUS"):
        decode_accel(encode_json(Kind.STATUS, {"t_ns": 1, "state": "x"}))
    with pytest.raises(PayloadError, match=r"payload version 9 is not supported"):
        decode_accel(good[:4] + b"\x09\x00" + good[6:])
    with pytest.raises(PayloadError, match=r"t_ns must be a 1-D integer array, got float64 of shape \(3,\)"):
        encode_accel(np.array([1.0, 2.0, 3.0]), np.zeros((3, 3)))
    with pytest.raises(PayloadError, match=r"acc must be a numeric \(3, 3\) array, got float64 of shape \(3, 2\)"):
        encode_accel(np.array([1, 2, 3]), np.zeros((3, 2)))
    with pytest.raises(PayloadError, match=r"accel acc must be finite"):
        encode_accel(np.array([1]), np.array([[0.0, np.inf, 0.0]]))


def test_every_telemetry_kind_has_a_payload_kind() -> None:
    assert set(TELEMETRY_PAYLOADS) == {"status", "accel", "detection", "run"}
    assert set(TELEMETRY_PAYLOADS.values()) | {Kind.CONTROL_REQUEST, Kind.CONTROL_REPLY} == set(Kind)


# ----- session configuration ----------------------------------------------------------------------------------


def test_session_config_is_loopback_only_without_scouting() -> None:
    config = session_config(listen=["tcp/127.0.0.1:7447"], connect=["tcp/[::1]:7448"])
    assert json.loads(config.get_json("mode")) == "peer"
    assert json.loads(config.get_json("listen/endpoints")) == ["tcp/127.0.0.1:7447"]
    assert json.loads(config.get_json("connect/endpoints")) == ["tcp/[::1]:7448"]
    assert json.loads(config.get_json("scouting/multicast/enabled")) is False
    assert json.loads(config.get_json("scouting/gossip/enabled")) is False
    queue = json.loads(config.get_json("transport/link/tx/queue/size"))  # zenoh's own key: 2 batches by default
    assert queue["data"] == TX_QUEUE_BATCHES == 16 and queue["control"] == 2
    only_connect = session_config(connect=[loopback_endpoint(7447)])
    assert json.loads(only_connect.get_json("listen/endpoints")) == []  # not zenoh's default tcp/[::]:0


@pytest.mark.parametrize(("endpoint", "message"), [
    ("tcp/0.0.0.0:7447", r"'tcp/0\.0\.0\.0:7447' is off loopback and not encrypted: use tls/0\.0\.0\.0:7447"),
    ("tcp/[::]:7447", r"is off loopback and not encrypted: use tls/\[::\]:7447"),
    ("udp/192.168.1.20:7447", r"is off loopback and not encrypted.*--insecure-plain-tcp"),
    ("tls/192.168.1.20:7447", r"is TLS but no TLS identity is given \(--tls-ca, --tls-cert, --tls-key\)"),
    ("tcp/localhost:7447", r"is not of the form tls/ADDRESS:PORT, tcp/127\.0\.0\.1:PORT, tcp/\[::1\]:PORT "
                           r"\(or udp/\.\.\.\)"),
    ("quic/127.0.0.1:7447", r"is not of the form"),
    ("tcp/127.0.0.1", r"is not of the form"),
    ("tcp/127.0.0.1:0", r"needs an explicit port in 1\.\.65535"),
    ("tcp/127.0.0.1:70000", r"needs an explicit port in 1\.\.65535"),
    ("tcp/127.0.0.300:7447", r"has no valid IP address"),
])
def test_endpoint_errors(endpoint: str, message: str) -> None:
    with pytest.raises(EndpointError, match=message):
        session_config(listen=[endpoint])


def test_session_config_errors() -> None:
    with pytest.raises(EndpointError, match="neither listen nor connect endpoints reaches nobody"):
        session_config()
    with pytest.raises(EndpointError, match="sequences of endpoints, not one string"):
        session_config(listen="tcp/127.0.0.1:7447")
    assert check_endpoint("udp/127.0.0.2:9") == "udp/127.0.0.2:9"


# ----- two real sessions --------------------------------------------------------------------------------------


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture
def sessions() -> Iterator[tuple[zenoh.Session, zenoh.Session]]:
    """The rig service's session listening on a loopback port, and a client session connecting to it."""
    endpoint = loopback_endpoint(_free_port())
    service = zenoh.open(session_config(listen=[endpoint]))
    try:
        client = zenoh.open(session_config(connect=[endpoint]))
        try:
            yield service, client
        finally:
            client.close()
    finally:
        service.close()


def _until(predicate, what: str) -> None:
    pause = threading.Event()
    for _ in range(int(WAIT / 0.01)):
        if predicate():
            return
        pause.wait(0.01)
    raise AssertionError(f"timed out waiting for {what}")


def test_sessions_are_connected_only_to_each_other(sessions) -> None:
    service, client = sessions
    _until(lambda: client.info.peers_zid() == [service.zid()], "the client to see the service as its peer")
    assert service.info.peers_zid() == [client.zid()]


def _deliver(publisher: zenoh.Publisher, payload: bytes, inbox: queue.Queue) -> zenoh.Sample:
    """Put ``payload`` until a sample arrives in ``inbox``: a publisher's matching status turns true a moment before
    the route carries data, and a put in that moment is lost (about one in four right after declaring, here)."""
    for _ in range(int(WAIT / 0.05)):
        publisher.put(payload)
        try:
            return inbox.get(timeout=0.05)
        except queue.Empty:
            continue
    raise AssertionError(f"nothing arrived on {publisher.key_expr}")


def test_telemetry_publication_reaches_a_subscriber(sessions) -> None:
    service, client = sessions
    inboxes = {telemetry_key(RIG, "status"): queue.Queue(), telemetry_key(RIG, "accel", "plate"): queue.Queue()}
    subscriber = client.declare_subscriber(telemetry_selector(RIG), lambda s: inboxes[str(s.key_expr)].put(s))
    status = service.declare_publisher(telemetry_key(RIG, "status"))
    accel = service.declare_publisher(telemetry_key(RIG, "accel", "plate"))
    _until(lambda: status.matching_status and accel.matching_status, "the publishers to match the subscriber")

    body = {"t_ns": 123, "state": "running", "buffer_depth": 40}
    sample = _deliver(status, encode_json(Kind.STATUS, body), inboxes[telemetry_key(RIG, "status")])
    assert decode_json(sample.payload.to_bytes(), TELEMETRY_PAYLOADS[parse_key(sample.key_expr).name]) == body

    t, acc = np.arange(5, dtype=np.int64) * 1_000_000, np.linspace(-1, 1, 15).reshape(5, 3)
    sample = _deliver(accel, encode_accel(t, acc), inboxes[telemetry_key(RIG, "accel", "plate")])
    assert parse_key(sample.key_expr) == Key(RIG, "telemetry", "accel", "plate")
    batch = decode_accel(sample.payload.to_bytes())
    np.testing.assert_array_equal(batch.t_ns, t)
    np.testing.assert_array_equal(batch.acc, acc)
    subscriber.undeclare()


def test_service_queryable_answers_a_control_query(sessions) -> None:
    service, client = sessions
    served: list[dict] = []
    errors: list[BaseException] = []

    def serve(query: zenoh.Query) -> None:
        try:
            key = parse_key(query.key_expr)
            request = decode_json(query.payload.to_bytes(), Kind.CONTROL_REQUEST)
            served.append(request)
            ok = request["command"] == key.name
            reply = {"ok": ok, "state": "paused" if ok else "idle", "message": "" if ok else "command/key mismatch",
                     "echo": request["args"]}
            query.reply(query.key_expr, encode_json(Kind.CONTROL_REPLY, reply))
        except Exception as exc:  # zenoh would only log it
            errors.append(exc)

    queryable = service.declare_queryable(service_selector(RIG), serve)
    querier = client.declare_querier(service_key(RIG, "pause"), timeout=WAIT)
    _until(lambda: querier.matching_status, "the querier to match the service's queryable")
    request = encode_json(Kind.CONTROL_REQUEST, {"command": "pause", "args": {"at": "end of record"}})
    replies: list[zenoh.Reply] = []
    _until(lambda: replies.extend(querier.get(payload=request)) or replies, "a reply")  # as _deliver: early gets
    assert len(replies) == 1 and len(served) == 1 and errors == []  # a lost get never reached the queryable
    assert replies[0].ok is not None
    assert str(replies[0].ok.key_expr) == service_key(RIG, "pause")
    assert decode_json(replies[0].ok.payload.to_bytes(), Kind.CONTROL_REPLY) == {
        "ok": True, "state": "paused", "message": "", "echo": {"at": "end of record"}}
    querier.undeclare()
    queryable.undeclare()


def test_liveliness_token_is_seen_by_the_other_session(sessions) -> None:
    service, client = sessions
    changes: queue.Queue[zenoh.Sample] = queue.Queue()
    watcher = client.liveliness().declare_subscriber(alive_selector(), changes.put, history=True)
    token = service.liveliness().declare_token(alive_key(RIG, "service"))
    appeared = changes.get(timeout=WAIT)
    assert (str(appeared.key_expr), appeared.kind) == (alive_key(RIG, "service"), zenoh.SampleKind.PUT)
    assert parse_key(appeared.key_expr) == Key(RIG, "alive", "service")
    replies = list(client.liveliness().get(alive_selector(RIG), timeout=WAIT))
    assert [str(r.ok.key_expr) for r in replies] == [alive_key(RIG, "service")]
    token.undeclare()
    gone = changes.get(timeout=WAIT)
    assert (str(gone.key_expr), gone.kind) == (alive_key(RIG, "service"), zenoh.SampleKind.DELETE)
    watcher.undeclare()
