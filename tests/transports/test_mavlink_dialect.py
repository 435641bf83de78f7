"""The MAVLink dialect: pinned ids and CRC seeds, generation and its cache, framing, signing, real UDP links.

Everything runs real pymavlink code (mavgen, the generated MAVLink classes, sockets on 127.0.0.1); nothing is
mocked except where a test injects a failure or a concurrent process into the generator.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import math
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocols.mavlink import (
    ACCEL_PER_BATCH,
    END_OF_STREAM,
    REPLAY_WINDOW,
    SETPOINTS_PER_CHUNK,
    STAMP_AHEAD,
    TILT_PER_BATCH,
    DialectError,
    FramingError,
    SequenceGapError,
    UdpLink,
    accel_batches,
    badly_signed,
    codegen,
    dialect,
    enable_signing,
    join_accel_batches,
    join_setpoint_chunks,
    mavlink_connection,
    parse_guarded,
    replay_guard,
    requires_signature,
    setpoint_chunks,
    signed_with_key,
    tilt_batches,
    unpack_accel_batch,
    unpack_setpoint_chunk,
    unpack_tilt_batch,
    whole_frames,
)
from protocols.mavlink.signing import signing_timestamp
from protocols.replay import Freshness
from protocols.signing_key import SigningKeyError

# A schema change must show up here: update the numbers together with both ends of the link.
PINNED = {  # name: (message id, CRC_EXTRA)
    "SHAKETABLE_SETPOINT_CHUNK": (42500, 97),
    "SHAKETABLE_ACCEL_BATCH": (42501, 143),
    "SHAKETABLE_OVERTURN_EVENT": (42502, 232),
    "SHAKETABLE_STATUS": (42503, 161),
    "SHAKETABLE_TILT_BATCH": (42504, 51),
    "SHAKETABLE_BODY": (42505, 200),
    "SHAKETABLE_CHUNK_REFUSED": (42506, 33),
    "SHAKETABLE_OWNER": (42507, 168),
    "SHAKETABLE_LIMIT_TRIP": (42508, 239),
}
COMMANDS = {
    "MAV_CMD_SHAKETABLE_ARM": 42550,
    "MAV_CMD_SHAKETABLE_DISARM": 42551,
    "MAV_CMD_SHAKETABLE_HOME": 42552,
    "MAV_CMD_SHAKETABLE_SET_TILT": 42553,
    "MAV_CMD_SHAKETABLE_START_STREAM": 42554,
    "MAV_CMD_SHAKETABLE_STOP": 42555,
    "MAV_CMD_SHAKETABLE_EMERGENCY_STOP": 42556,
    "MAV_CMD_SHAKETABLE_CLAIM": 42557,
    "MAV_CMD_SHAKETABLE_RELEASE": 42558,
    "MAV_CMD_SHAKETABLE_SET_LIMIT": 42559,
}
KEY = bytes(range(1, 33))
HOST = (255, 190)  # system, component of the lab host
TABLE = (1, 1)


@pytest.fixture(scope="module")
def d(tmp_path_factory):
    """The project's dialect, generated into a private cache unless this process already has it."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("cache")))
        return dialect()


@pytest.fixture
def cache(tmp_path, monkeypatch) -> Path:
    """An empty cache root for generation tests; returns ``.../shaketable-rig/mavlink``."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    return tmp_path / "xdg" / "shaketable-rig" / "mavlink"


def _copy_xml(tmp_path: Path, old: str = "", new: str = "", name: str = "copy.xml") -> Path:
    text = codegen.XML_PATH.read_text()
    if old:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text)
    return path


def _count_mavgen(monkeypatch) -> list[Path]:
    calls: list[Path] = []
    real = codegen._run_mavgen

    def counting(sources, module_path):
        calls.append(module_path)
        real(sources, module_path)

    monkeypatch.setattr(codegen, "_run_mavgen", counting)
    return calls


def _mav(d, ids=HOST, key=None, link_id=0):
    """A dialect MAVLink object that collects what it sends in ``.file.out``."""

    class Sink:
        def __init__(self):
            self.out: list[bytes] = []

        def write(self, buf):
            self.out.append(bytes(buf))

    mav = d.MAVLink(Sink(), srcSystem=ids[0], srcComponent=ids[1])
    if key is not None:
        enable_signing(mav, key, link_id=link_id)
    return mav


def _transfer(msg, sender, receiver):
    """Encode ``msg`` with ``sender``, parse the bytes with ``receiver``; the single message received."""
    sender.send(msg)
    got = receiver.parse_buffer(sender.file.out[-1])
    assert got is not None and len(got) == 1
    return got[0]


# ---------------------------------------------------------------- the schema, pinned


def test_message_ids_and_crc_extra_are_pinned(d):
    mine = {cls.msgname: (mid, cls.crc_extra) for mid, cls in d.mavlink_map.items() if 42500 <= mid <= 42509}
    assert mine == PINNED
    for mid, _ in PINNED.values():
        assert d.mavlink_map[mid].unpacker.size <= 255  # MAVLink 2 payload limit
    assert d.WIRE_PROTOCOL_VERSION == "2.0"
    assert d.DIALECT == "shaketable"


def test_commands_and_enums_are_pinned(d):
    assert {name: getattr(d, name) for name in COMMANDS} == COMMANDS
    assert {e.name for v, e in d.enums["MAV_CMD"].items() if 42550 <= v <= 42559} == set(COMMANDS)
    assert d.enums["MAV_CMD"][42553].param[1].startswith("Tilt angle beta [rad]")
    assert [d.enums["SHAKETABLE_STATE"][v].name.removeprefix("SHAKETABLE_STATE_") for v in range(9)] == [
        "IDLE", "ARMED", "HOMING", "TILTING", "STREAMING", "HOLDING", "STOPPING", "FAULTED", "EMERGENCY_STOPPED"]
    faults = {e.name.removeprefix("SHAKETABLE_FAULT_"): v for v, e in d.enums["SHAKETABLE_FAULT"].items()
              if not e.name.endswith("_ENUM_END")}
    assert faults == {"DRIVE": 1, "STROKE": 2, "STREAM_SILENT": 4, "HEARTBEAT_LOST": 8, "UNSIGNED_COMMAND": 16,
                      "SETPOINT_LIMIT": 32, "CHUNK_GAP": 64, "UNDERRUN": 128,
                      "SETPOINT_REFUSED": 256}
    assert (d.SHAKETABLE_TILT_AXIS_PITCH, d.SHAKETABLE_TILT_AXIS_ROLL) == (0, 1)
    assert d.SHAKETABLE_CHUNK_FLAGS_END_OF_STREAM == END_OF_STREAM


def test_reserved_numbers_are_free_in_every_bundled_dialect(d):
    """common.xml's clashes would already stop mavgen; 'all' also holds every vendor dialect pymavlink ships."""
    from pymavlink.dialects.v20 import all as everything

    assert not set(everything.mavlink_map) & set(range(42500, 42510))
    assert not set(everything.enums["MAV_CMD"]) & set(range(42550, 42560))


def test_framing_constants_match_the_generated_messages(d):
    chunk = d.MAVLink_shaketable_setpoint_chunk_message
    batch = d.MAVLink_shaketable_accel_batch_message
    tilt = d.MAVLink_shaketable_tilt_batch_message
    assert max(chunk.array_lengths) == SETPOINTS_PER_CHUNK * 6
    assert max(batch.array_lengths) == ACCEL_PER_BATCH * 3
    assert batch.unpacker.size + 3 * 4 > 255  # one more sample would not fit
    assert max(tilt.array_lengths) == TILT_PER_BATCH
    assert tilt.unpacker.size == 255  # full: one more angle would not fit


def test_changing_a_field_type_changes_its_crc_and_only_its_own(d, cache, tmp_path, monkeypatch):
    calls = _count_mavgen(monkeypatch)
    changed = codegen.load(_copy_xml(tmp_path, '<field type="uint8_t" name="count">Number of samples used, 1 to 8',
                                         '<field type="uint16_t" name="count">Number of samples used, 1 to 8'))
    assert len(calls) == 1 and calls[0].is_relative_to(cache)
    crcs = {name: changed.mavlink_map[mid].crc_extra for name, (mid, _) in PINNED.items()}
    assert crcs["SHAKETABLE_SETPOINT_CHUNK"] != PINNED["SHAKETABLE_SETPOINT_CHUNK"][1]
    assert {k: v for k, v in crcs.items() if k != "SHAKETABLE_SETPOINT_CHUNK"} == {
        k: crc for k, (_, crc) in PINNED.items() if k != "SHAKETABLE_SETPOINT_CHUNK"}
    # and a message of the old schema no longer decodes under the new one
    old = _mav(d)
    old.send(setpoint_chunks(np.zeros((1, 6)), 0, 1)[0])
    with pytest.raises(changed.MAVError, match="invalid MAVLink CRC"):
        changed.MAVLink(None).parse_buffer(old.file.out[-1])


# ---------------------------------------------------------------- generation and its cache


def test_generated_module_is_reused_not_regenerated(d, cache, tmp_path, monkeypatch):
    calls = _count_mavgen(monkeypatch)
    xml = _copy_xml(tmp_path)
    first = codegen.build(xml)
    assert first == cache / codegen.cache_key(xml) / "shaketable.py"
    stat = first.stat()
    assert codegen.build(xml) == first
    assert len(calls) == 1
    assert (first.stat().st_ino, first.stat().st_mtime_ns) == (stat.st_ino, stat.st_mtime_ns)
    assert "DO NOT EDIT" in first.read_text()[:400]


def test_the_generated_module_is_imported_from_its_byte_code(d, cache, tmp_path, monkeypatch):
    """Its byte code is written beside it even where Python writes none (PYTHONDONTWRITEBYTECODE), also for a
    cached module that has none, and the import system loads it: no 0.4 s compile holding the interpreter lock in
    every process."""
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    module_path = codegen.build(_copy_xml(tmp_path))
    cached = Path(importlib.util.cache_from_source(str(module_path)))
    assert cached.is_file()
    cached.unlink()  # a module cached before byte code was written
    assert codegen.build(_copy_xml(tmp_path)) == module_path and cached.is_file()
    loader = importlib.machinery.SourceFileLoader("dialect_probe", str(module_path))
    code = loader.get_code("dialect_probe")
    assert code is not None and code.co_filename == str(module_path)
    monkeypatch.setattr(loader, "source_to_code", lambda *a, **k: pytest.fail("compiled from source"))
    assert loader.get_code("dialect_probe") is not None  # from the byte code: source_to_code never called


def test_an_edited_xml_is_regenerated_under_a_new_key(d, cache, tmp_path, monkeypatch):
    calls = _count_mavgen(monkeypatch)
    xml = _copy_xml(tmp_path)
    first = codegen.build(xml)
    xml.write_text(xml.read_text().replace("Controller state.", "Controller state (SHAKETABLE_STATE)."))
    second = codegen.build(xml)
    assert second != first and second.parent.parent == first.parent.parent
    assert len(calls) == 2 and first.is_file() and second.is_file()
    assert "Controller state (SHAKETABLE_STATE)." in second.read_text()


def test_the_cache_follows_xdg_cache_home_and_pymavlinks_version(d, tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "a"))
    assert codegen.cache_root() == tmp_path / "a" / "shaketable-rig" / "mavlink"
    key = codegen.cache_key()
    monkeypatch.setattr(codegen.importlib.metadata, "version", lambda name: "0.0.0")
    assert codegen.cache_key() != key


@pytest.mark.parametrize(("old", "new", "why"), [
    ('<message id="42503"', '<message id="0"', "Duplicate message id"),  # clashes with HEARTBEAT
    ('units="m/s/s"', 'units="m/s^2"', "m/s^2"),  # not a MAVLink unit: schema validation fails
    ("<include>ardupilotmega.xml</include>", "<include>nowhere.xml</include>", "nowhere.xml"),
])
def test_a_rejected_dialect_raises_and_leaves_nothing(d, cache, tmp_path, old, new, why):
    xml = _copy_xml(tmp_path, old, new)
    with pytest.raises(DialectError, match=why.replace("^", r"\^")):
        codegen.load(xml)
    assert not cache.exists() or list(cache.iterdir()) == []


def test_generation_that_dies_half_way_leaves_no_importable_module(d, cache, tmp_path, monkeypatch):
    def dies(sources, module_path):
        module_path.write_text("MAVLink = None\n# ...the rest never written")
        raise DialectError("killed")

    monkeypatch.setattr(codegen, "_run_mavgen", dies)
    xml = _copy_xml(tmp_path)
    with pytest.raises(DialectError, match="killed"):
        codegen.build(xml)
    assert list(cache.iterdir()) == []  # no key directory, no staging left over
    monkeypatch.undo()
    monkeypatch.setenv("XDG_CACHE_HOME", str(cache.parent.parent))
    assert "class MAVLink(" in codegen.build(xml).read_text()


def test_a_race_lost_to_another_process_uses_the_winners_module(d, cache, tmp_path, monkeypatch):
    real = codegen._run_mavgen
    xml = _copy_xml(tmp_path)
    target = cache / codegen.cache_key(xml)

    def other_process_finishes_first(sources, module_path):
        real(sources, module_path)
        shutil.copytree(module_path.parent, target)  # the winner's complete rename
        (target / "shaketable.py").write_text((target / "shaketable.py").read_text() + "\nWINNER = True\n")

    monkeypatch.setattr(codegen, "_run_mavgen", other_process_finishes_first)
    path = codegen.build(xml)
    assert path == target / "shaketable.py" and path.read_text().endswith("WINNER = True\n")
    assert [p.name for p in cache.iterdir()] == [target.name]  # the loser's staging directory is gone


def test_old_cache_entries_are_pruned(d, cache, tmp_path):
    xml = _copy_xml(tmp_path)
    codegen.build(xml)
    old, recent = cache / "0123456789abcdef", cache / ".staging-recent"
    for p in (old, recent):
        p.mkdir()
    stale = time.time() - (codegen.KEEP_DAYS + 1) * 86400
    os.utime(old, (stale, stale))
    codegen.build(xml)
    assert not old.exists() and recent.exists()


def test_dialect_is_one_module_registered_for_mavutil(d):
    import pymavlink.dialects.v20 as v20
    from pymavlink.dialects.v20 import shaketable

    assert dialect() is d is shaketable is v20.shaketable


# ---------------------------------------------------------------- encode → bytes → decode


def _examples(d):
    chunk = setpoint_chunks(np.linspace(-0.2, 0.3, 8 * 6).reshape(8, 6), 123_456_789_012, 1_000_000, 77,
                            end_of_stream=True)[0]
    batch = accel_batches(np.linspace(-9.81, 9.81, 19 * 3).reshape(19, 3), 3, 2**40, 500_000, 2**32 - 1)[0]
    tilt = tilt_batches(np.linspace(-1.6, 1.6, 59), 65_535, 2**40, 5_000_000, 2**32 - 1)[0]
    return [
        chunk,
        batch,
        tilt,
        d.MAVLink_shaketable_overturn_event_message(event_id=4_000_000_000, body_id=65_535, direction=-1,
                                                    tilt=0.0872665, t_ns=2**63 + 5),
        d.MAVLink_shaketable_status_message(t_ns=987_654_321, state=d.SHAKETABLE_STATE_STREAMING, buffer_depth=96,
                                            last_chunk_seq=41, underruns=3,
                                            faults=d.SHAKETABLE_FAULT_UNDERRUN | d.SHAKETABLE_FAULT_STROKE,
                                            refused_commands=2, pose=[0.01, -0.02, 0.003, 0.0, 0.0873, -0.001],
                                            following_error=[0.0004, -0.0006, 0.0, 0.0052, -0.0001, 0.0]),
        d.MAVLink_shaketable_limit_trip_message(t_ns=2**63 + 7, value=6.02, level=5.886, code=98_307, sensor=3),
        *[d.MAVLink_command_long_message(TABLE[0], TABLE[1], value, 0, 0.0873 if name.endswith("TILT") else 0,
                                         d.SHAKETABLE_TILT_AXIS_ROLL if name.endswith("TILT") else 0, 0, 0, 0, 0, 0)
          for name, value in COMMANDS.items()],
    ]


def _fields_equal(a, b):
    for name in a.fieldnames:
        x, y = getattr(a, name), getattr(b, name)
        if isinstance(x, float | list):
            np.testing.assert_array_equal(np.float32(x), np.float32(y), err_msg=name)
        else:
            assert x == y, name


@pytest.mark.parametrize("signed", [False, True])
def test_every_message_round_trips_in_mavlink2(d, signed):
    key = KEY if signed else None
    host, table = _mav(d, HOST, key, link_id=7), _mav(d, TABLE, key)
    for msg in _examples(d):
        got = _transfer(msg, host, table)
        raw = host.file.out[-1]
        assert raw[0] == 0xFD and bool(raw[2] & 0x01) is signed  # MAVLink 2 magic; incompat flag "signed"
        assert got.get_type() == msg.get_type() and got.get_msgId() == msg.get_msgId()
        assert (got.get_srcSystem(), got.get_srcComponent()) == HOST
        assert signed_with_key(got) is signed
        _fields_equal(msg, got)
        if signed:
            assert got._link_id == 7


# ---------------------------------------------------------------- signing


def test_signature_verifies_only_with_the_right_key(d):
    chunk = setpoint_chunks(np.ones((3, 6)), 0, 1_000_000)[0]
    host = _mav(d, HOST, KEY)
    good = _mav(d, TABLE, KEY)
    assert signed_with_key(_transfer(chunk, host, good))

    wrong = _mav(d, TABLE, bytes(reversed(KEY)))
    flagged = _transfer(chunk, host, wrong)  # delivered, so that the policy can refuse it and say so
    assert not signed_with_key(flagged) and wrong.signing.badsig_count == 1

    assert not signed_with_key(_transfer(chunk, _mav(d, HOST), good))  # unsigned
    assert not signed_with_key(_transfer(chunk, host, _mav(d, TABLE)))  # receiver without a key checks nothing

    replay = good.parse_buffer(host.file.out[0])  # the first signed frame again: stale timestamp
    assert replay is not None and not signed_with_key(replay[0])

    tampered = bytearray(host.file.out[-1])
    tampered[-1] ^= 0xFF  # last byte of the signature
    assert not signed_with_key(good.parse_buffer(bytes(tampered))[0])


def test_stopping_needs_no_signature_everything_else_that_moves_does(d):
    def command(value, kind="long"):
        if kind == "int":
            return d.MAVLink_command_int_message(1, 1, 0, value, 0, 0, 0, 0, 0, 0, 0, 0, 0)
        return d.MAVLink_command_long_message(1, 1, value, 0, 0, 0, 0, 0, 0, 0, 0)

    needs = {name: requires_signature(command(value)) for name, value in COMMANDS.items()}
    assert needs == {name: not name.endswith(("DISARM", "_STOP")) for name in COMMANDS}
    assert requires_signature(command(d.MAV_CMD_SHAKETABLE_ARM, "int"))
    assert requires_signature(command(d.MAV_CMD_COMPONENT_ARM_DISARM))  # unknown commands: default deny
    assert requires_signature(setpoint_chunks(np.zeros((1, 6)), 0, 1)[0])
    assert not requires_signature(d.MAVLink_heartbeat_message(0, 0, 0, 0, 0, 3))
    assert not requires_signature(_examples(d)[3])  # status


def test_enable_signing_refuses_a_bad_key_or_link_id(d):
    with pytest.raises(SigningKeyError, match="32 bytes, got 16"):
        enable_signing(_mav(d), KEY[:16], link_id=0)
    with pytest.raises(ValueError, match="link_id"):
        enable_signing(_mav(d), KEY, link_id=256)


# ---------------------------------------------------------------- framing


def test_setpoints_split_into_full_chunks_and_a_zero_padded_last_one(d):
    poses = np.arange(19 * 6, dtype=float).reshape(19, 6) / 7
    chunks = setpoint_chunks(poses, 5_000, 1_000, first_seq=10, end_of_stream=True)
    assert [(c.chunk_seq, c.t_start_ns, c.spacing_ns, c.count, c.flags) for c in chunks] == [
        (10, 5_000, 1_000, 8, 0), (11, 13_000, 1_000, 8, 0), (12, 21_000, 1_000, 3, END_OF_STREAM)]
    assert chunks[-1].samples[18:] == [0.0] * 30
    last = unpack_setpoint_chunk(chunks[-1])
    np.testing.assert_array_equal(last.samples, poses[16:].astype(np.float32))
    np.testing.assert_array_equal(last.times_ns(), [21_000, 22_000, 23_000])
    assert setpoint_chunks(np.empty((0, 6)), 0, 1) == []
    assert [c.count for c in setpoint_chunks(np.zeros((16, 6)), 0, 1)] == [8, 8]


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 60), seed=st.integers(0, 2**32 - 1), first_seq=st.integers(0, 2**32 - 1),
       t_start=st.integers(0, 2**62), spacing=st.integers(1, 2**32 - 1))
def test_setpoint_chunks_join_back_exactly(n, seed, first_seq, t_start, spacing):
    poses = np.random.default_rng(seed).normal(scale=0.1, size=(n, 6))
    series = join_setpoint_chunks(setpoint_chunks(poses, t_start, spacing, first_seq), first_seq=first_seq)
    assert (series.t_start_ns, series.spacing_ns) == (t_start, spacing)
    np.testing.assert_array_equal(series.samples, poses.astype(np.float32).astype(np.float64))
    assert series.end_ns == t_start + n * spacing


def test_accel_batches_join_back_exactly_across_the_sequence_wrap():
    accel = np.random.default_rng(5).normal(scale=3.0, size=(100, 3))
    batches = accel_batches(accel, 2, 10**12, 1_000_000, first_seq=2**32 - 2)
    assert [b.batch_seq for b in batches] == [2**32 - 2, 2**32 - 1, 0, 1, 2, 3]
    assert [b.count for b in batches] == [19] * 5 + [5] and {b.sensor_id for b in batches} == {2}
    series = join_accel_batches(batches)
    np.testing.assert_array_equal(series.samples, accel.astype(np.float32))
    one = unpack_accel_batch(batches[2])
    assert one.t_start_ns == 10**12 + 38 * 1_000_000 and one.samples.shape == (19, 3)


def test_tilt_batches_unpack_exactly_with_their_body_sequence_and_times():
    angles = np.random.default_rng(6).normal(scale=0.5, size=130)
    batches = tilt_batches(angles, 513, 10**12, 5_000_000, first_seq=2**32 - 1)
    assert [b.batch_seq for b in batches] == [2**32 - 1, 0, 1]
    assert [b.count for b in batches] == [59, 59, 12] and {b.body_id for b in batches} == {513}
    parts = [unpack_tilt_batch(b) for b in batches]
    assert [p.t_start_ns for p in parts] == [10**12, 10**12 + 59 * 5_000_000, 10**12 + 118 * 5_000_000]
    assert all(p.spacing_ns == 5_000_000 and p.samples.shape == (p.samples.shape[0], 1) for p in parts)
    np.testing.assert_array_equal(np.concatenate([p.samples[:, 0] for p in parts]), angles.astype(np.float32))
    assert parts[-1].end_ns == 10**12 + 130 * 5_000_000
    assert tilt_batches([], 0, 0, 1) == []
    with pytest.raises(ValueError, match="body_id"):
        tilt_batches([0.1], 2**16, 0, 1)
    with pytest.raises(ValueError, match=r"shape \(N,\)"):
        tilt_batches(np.zeros((2, 1)), 0, 0, 1)
    with pytest.raises(ValueError, match="finite"):
        tilt_batches([math.nan], 0, 0, 1)
    with pytest.raises(FramingError, match="expected SHAKETABLE_TILT_BATCH"):
        unpack_tilt_batch(accel_batches(np.zeros((1, 3)), 0, 0, 1)[0])


def test_joining_detects_lost_repeated_and_inconsistent_messages(d):
    chunks = setpoint_chunks(np.zeros((40, 6)), 0, 1_000, first_seq=3, end_of_stream=True)
    with pytest.raises(SequenceGapError, match="5 where 4") as gap:
        join_setpoint_chunks(chunks[:1] + chunks[2:])
    assert (gap.value.expected, gap.value.got) == (4, 5)
    with pytest.raises(SequenceGapError):
        join_setpoint_chunks(chunks[:2] + chunks[1:])
    with pytest.raises(SequenceGapError, match="3 where 0"):
        join_setpoint_chunks(chunks, first_seq=0)
    shifted = setpoint_chunks(np.zeros((8, 6)), 9_000, 1_000, first_seq=4)
    with pytest.raises(FramingError, match="starts at 9000 ns, the stream continues at 8000 ns"):
        join_setpoint_chunks(chunks[:1] + shifted)
    respaced = setpoint_chunks(np.zeros((8, 6)), 8_000, 2_000, first_seq=4)
    with pytest.raises(FramingError, match="spacing 2000 ns after 1000 ns"):
        join_setpoint_chunks(chunks[:1] + respaced)
    after_end = setpoint_chunks(np.zeros((8, 6)), 40_000, 1_000, first_seq=8)
    with pytest.raises(FramingError, match="follows the end of the stream"):
        join_setpoint_chunks(chunks + after_end)
    sensors = accel_batches(np.zeros((19, 3)), 1, 0, 10) + accel_batches(np.zeros((19, 3)), 2, 190, 10, 1)
    with pytest.raises(FramingError, match="sensor_id 2 in a stream of 1"):
        join_accel_batches(sensors)
    with pytest.raises(FramingError, match="expected SHAKETABLE_ACCEL_BATCH"):
        join_accel_batches(chunks)
    with pytest.raises(FramingError, match="no SHAKETABLE_SETPOINT_CHUNK"):
        join_setpoint_chunks([])
    broken = d.MAVLink_shaketable_setpoint_chunk_message(0, 0, 1_000, 9, 0, [0.0] * 48)
    with pytest.raises(FramingError, match=r"count 9 outside 1\.\.8"):
        unpack_setpoint_chunk(broken)


@pytest.mark.parametrize(("args", "why"), [
    ((np.zeros((3, 5)), 0, 1), r"shape \(N, 6\)"),
    ((np.array([[0, 0, np.nan, 0, 0, 0]]), 0, 1), "finite"),
    ((np.full((1, 6), 1e39), 0, 1), "float32 range"),
    ((np.zeros((1, 6)), 0, 0), "spacing_ns"),
    ((np.zeros((1, 6)), -1, 1), "t_start_ns"),
    ((np.zeros((3, 6)), 2**64 - 2, 1), "t_start_ns"),  # the last sample's time would not fit uint64
    ((np.zeros((1, 6)), 0, 1, 2**32), "first_seq"),
])
def test_setpoints_that_do_not_fit_the_wire_are_refused(d, args, why):
    with pytest.raises(ValueError, match=why):
        setpoint_chunks(*args)


# ---------------------------------------------------------------- real links over UDP on 127.0.0.1


def _receive_all(link, want, kinds, rounds=400):
    got = []
    for _ in range(rounds):
        if len(got) >= want:
            break
        got.extend(m for m in link.receive(timeout=2.0) if m.get_type() in kinds)
    return got


@pytest.mark.integration
def test_udp_loopback_streams_setpoints_and_accelerations_exactly(d):
    rng = np.random.default_rng(11)
    poses = rng.normal(scale=0.05, size=(203, 6))
    accel = {0: rng.normal(size=(150, 3)), 1: rng.normal(size=(77, 3))}
    with UdpLink.open(source_system=TABLE[0], source_component=TABLE[1], key=KEY,
                      receive_buffer=1 << 20) as table, \
            UdpLink.open(peer=table.local_address, source_system=HOST[0], source_component=HOST[1], key=KEY,
                         link_id=1, receive_buffer=1 << 20) as host:
        assert table.local_address[0] == "127.0.0.1" and table.local_address[1] > 0
        chunks = setpoint_chunks(poses, 10**9, 1_000_000, first_seq=100, end_of_stream=True)
        for c in chunks:
            host.send(c)
        received = _receive_all(table, len(chunks), {"SHAKETABLE_SETPOINT_CHUNK"})
        assert table.peer == host.local_address  # learnt from the first datagram
        assert all(signed_with_key(m) and (m.get_srcSystem(), m.get_srcComponent()) == HOST for m in received)
        stream = join_setpoint_chunks(received, first_seq=100)
        np.testing.assert_array_equal(stream.samples, poses.astype(np.float32))
        assert stream.t_start_ns == 10**9 and received[-1].flags == END_OF_STREAM

        batches = [b for sensor, a in accel.items() for b in accel_batches(a, sensor, 10**9, 250_000)]
        for b in batches:
            table.send(b)
        back = _receive_all(host, len(batches), {"SHAKETABLE_ACCEL_BATCH"})
        for sensor, a in accel.items():
            series = join_accel_batches([b for b in back if b.sensor_id == sensor], first_seq=0)
            np.testing.assert_array_equal(series.samples, a.astype(np.float32))
        assert host.mav.total_receive_errors == 0 and table.mav.total_receive_errors == 0

        host.sock.sendto(b"\x00garbage", table.local_address)  # no MAVLink 2 frame: dropped unparsed, counted
        assert table.receive(timeout=2.0) == [] and table.junk == 1 and table.mav.total_receive_errors == 0
        frame = bytearray(host.mav.heartbeat_encode(0, 0, 0, 0, 0, 3).pack(host.mav))
        frame[-14] ^= 0xFF  # a whole frame with a bad checksum: pymavlink's to drop and count
        host.sock.sendto(bytes(frame), table.local_address)
        assert table.receive(timeout=2.0) == [] and table.mav.total_receive_errors > 0


@pytest.mark.integration
def test_udp_receive_without_traffic_returns_nothing(d):
    with UdpLink.open(source_system=1, source_component=1) as link:
        assert link.receive(timeout=0.0) == []
        with pytest.raises(ConnectionError, match="no peer"):
            link.send(d.MAVLink_heartbeat_message(0, 0, 0, 0, 0, 3))


@pytest.mark.integration
def test_mavutil_connection_speaks_the_dialect_signed(d, monkeypatch):
    monkeypatch.setenv("MAVLINK20", "1")  # restored afterwards; mavlink_connection sets it for mavutil
    table = mavlink_connection("udpin:127.0.0.1:0", source_system=TABLE[0], source_component=TABLE[1], key=KEY)
    port = table.port.getsockname()[1]
    host = mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=HOST[0], source_component=HOST[1],
                              key=KEY, link_id=2)
    try:
        assert isinstance(host.mav, d.MAVLink) and host.WIRE_PROTOCOL_VERSION == "2.0"
        host.mav.command_long_send(TABLE[0], TABLE[1], d.MAV_CMD_SHAKETABLE_SET_TILT, 0, 0.0873,
                                   d.SHAKETABLE_TILT_AXIS_PITCH, 0, 0, 0, 0, 0)
        cmd = table.recv_match(type="COMMAND_LONG", blocking=True, timeout=5)
        assert cmd is not None and cmd.command == d.MAV_CMD_SHAKETABLE_SET_TILT
        assert np.float32(cmd.param1) == np.float32(0.0873)
        assert signed_with_key(cmd) and requires_signature(cmd)
        table.mav.shaketable_overturn_event_send(9, 4, 1, 0.0873, 123)  # udpin answers the last sender
        event = host.recv_match(type="SHAKETABLE_OVERTURN_EVENT", blocking=True, timeout=5)
        assert event is not None and (event.event_id, event.body_id, event.direction) == (9, 4, 1)
        assert signed_with_key(event)
    finally:
        host.close()
        table.close()


# ----- what a receiver drops before pymavlink parses (issue 25) -------------------------------------------------


def _heartbeat(d, key: bytes | None = None, *, timestamp: int | None = None, system: int = 255) -> bytes:
    mav = d.MAVLink(None, srcSystem=system, srcComponent=190)
    if key is not None:
        enable_signing(mav, key, link_id=3, timestamp=timestamp)
    return d.MAVLink_heartbeat_message(d.MAV_TYPE_GCS, d.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3).pack(mav)


def test_whole_frames_splits_datagrams_and_refuses_junk(d):
    key = bytes(range(1, 33))
    unsigned, signed = _heartbeat(d), _heartbeat(d, key)
    # MAVLink 2 heartbeat: 10-byte header, 9-byte payload (none of it trailing zeros here), 2-byte CRC, 13 signed
    assert (len(unsigned), len(signed)) == (21, 34)
    assert whole_frames(unsigned + signed) == [unsigned, signed]
    junk = np.random.default_rng(1).bytes(1024)
    assert whole_frames(junk[1:] if junk[0] == 0xFD else junk) is None
    assert whole_frames(unsigned[:-1]) is None  # truncated
    assert whole_frames(unsigned + b"\x00") is None  # a trailing byte
    assert whole_frames(b"") is None


def test_a_new_stream_stamped_more_than_the_window_behind_the_wall_clock_is_stale(d):
    key = bytes(range(1, 33))
    receiver = d.MAVLink(None, srcSystem=1, srcComponent=1)
    enable_signing(receiver, key, link_id=0, sign_outgoing=False)
    guard = replay_guard()
    now = time.time()
    captured = _heartbeat(d, key, timestamp=signing_timestamp(now - 36.0))
    late = _heartbeat(d, key, timestamp=signing_timestamp(now - REPLAY_WINDOW - 0.5), system=254)
    fresh = _heartbeat(d, key, timestamp=signing_timestamp(now - REPLAY_WINDOW + 1.0), system=253)
    ahead = _heartbeat(d, key, timestamp=signing_timestamp(now + STAMP_AHEAD + 1.0), system=252)
    # pymavlink alone takes the 36 s old one (its window is a minute); found stale, it is unsigned and its stream
    # stays closed, so the rest of the capture is stale too
    for frame, freshness in ((captured, Freshness.STALE), (late, Freshness.STALE), (ahead, Freshness.FUTURE)):
        (refused,), found = parse_guarded(receiver, guard, frame)
        assert found is freshness and not signed_with_key(refused) and badly_signed(refused)
    assert receiver.signing.stream_timestamps == {} and guard.state().streams == ()
    (unsigned,), found = parse_guarded(receiver, guard, _heartbeat(d))
    assert found is None and not signed_with_key(unsigned)
    (taken,), found = parse_guarded(receiver, guard, fresh)
    assert found is Freshness.FRESH and signed_with_key(taken)
    assert list(receiver.signing.stream_timestamps) == [(3, 253, 190)]
    assert [stream for stream, _ in guard.state().streams] == [(3, 253, 190)]
    (again,), found = parse_guarded(receiver, guard, fresh)  # the same frame again: a replay within its stream
    assert found is Freshness.STALE and not signed_with_key(again)
