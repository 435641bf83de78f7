"""Replay protection that a clock jump cannot reset (issue 42, item 4): the guard's rules (protocols/replay.py) and
the controller's state file (sim_table/replay_store.py), in process, with clocks given by hand."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from protocols.replay import Freshness, ReplayGuard, ReplayState
from sim_table.replay_store import FORMAT, ReplayStateError, ReplayStore, default_path

S = 1_000  # stamp units per second in these tests


class Clock:
    """A wall clock set by hand [stamp units]."""

    def __init__(self, now: int) -> None:
        self.now = now

    def __call__(self) -> int:
        return self.now


def test_streams_rise_new_ones_open_near_the_current_stamp_and_none_runs_ahead() -> None:
    clock = Clock(100 * S)
    guard = ReplayGuard(clock, window=5 * S, ahead=5 * S)
    assert guard.admit("a", 100 * S) is Freshness.FRESH
    assert guard.admit("a", 100 * S) is Freshness.STALE  # the same stamp again: a replay
    assert guard.admit("a", 99 * S) is Freshness.STALE  # reordered
    assert guard.admit("b", 94 * S) is Freshness.STALE  # a new stream more than the window behind
    assert guard.admit("b", 96 * S) is Freshness.FRESH
    assert guard.admit("c", 106 * S) is Freshness.FUTURE  # more than `ahead` beyond the current stamp
    assert guard.admit("a", 106 * S) is Freshness.FUTURE  # a known stream too
    assert guard.admit("a", 104 * S) is Freshness.FRESH
    assert guard.current() == 104 * S  # the largest stamp taken leads a clock that is behind
    assert guard.check("d", 99 * S) is Freshness.FRESH and guard.check("d", 98 * S) is Freshness.STALE
    assert guard.check("d", 108 * S) is Freshness.FRESH  # ahead of the current stamp, not of the clock
    assert guard.state() == ReplayState(104 * S, (("b", 96 * S), ("a", 104 * S)))


def test_a_clock_that_jumps_back_does_not_reopen_the_window() -> None:
    """The issue's case: a restart with the clock 60 s behind, and a signed ARM captured 20 s before."""
    clock = Clock(980 * S)
    before = ReplayGuard(clock, window=5 * S, ahead=5 * S)
    assert before.admit("host", 980 * S) is Freshness.FRESH  # the ARM, heard when it was made
    clock.now = 1_000 * S
    assert before.admit("host", 1_000 * S) is Freshness.FRESH  # the host's later messages
    clock.now = 940 * S  # restarted, 60 s behind
    after = ReplayGuard(clock, window=5 * S, ahead=5 * S, state=before.state())
    assert after.check("host", 980 * S) is Freshness.STALE  # its stream's last stamp was kept
    assert after.check("other", 980 * S) is Freshness.STALE  # a stream it never heard: 20 s behind what it has
    assert after.check("other", 999 * S) is Freshness.FRESH  # a host on time still connects
    forgetful = ReplayGuard(clock, window=5 * S, ahead=5 * S)  # what the controller did before: wall clock only
    assert forgetful.check("host", 980 * S) is Freshness.FUTURE  # and now refused as from the future


def test_only_the_most_recent_streams_are_kept() -> None:
    guard = ReplayGuard(Clock(10 * S), window=5 * S, ahead=5 * S, remembered=2)
    for stream in ("a", "b", "c"):
        guard.admit(stream, 10 * S)
    guard.admit("b", 11 * S)
    assert [stream for stream, _ in guard.state().streams] == ["c", "b"]
    assert guard.check("a", 10 * S) is Freshness.FRESH  # forgotten: the window rule again


def test_the_state_file_round_trips_and_writes_only_what_changed(tmp_path: Path) -> None:
    path = default_path(tmp_path / "rig.key", "mavlink")
    assert path == tmp_path / "rig.key.mavlink-replay.json"
    store = ReplayStore(path, "mavlink")
    assert store.load() is None  # a first start
    guard = ReplayGuard(Clock(10 * S), window=5 * S, ahead=5 * S)
    store.keep(guard)
    try:
        guard.admit((3, 255, 190), 12 * S)
        guard.admit((0, 250, 190), 11 * S)
        assert store.save() and json.loads(path.read_text())["streams"] == [[[3, 255, 190], 12 * S],
                                                                             [[0, 250, 190], 11 * S]]
        written = path.stat().st_mtime_ns
        assert store.save() and path.stat().st_mtime_ns == written  # nothing new
    finally:
        assert store.close()
    assert ReplayStore(path, "mavlink").load() == guard.state()
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no temporary file left behind


def test_a_failed_write_leaves_the_last_state_whole_and_is_reported(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "replay.json"
    store = ReplayStore(path, "zenoh")
    guard = ReplayGuard(Clock(10 * S), window=5 * S, ahead=5 * S)
    store.keep(guard)
    try:
        guard.admit((7, "shaketable/t/controller/command"), 10 * S)
        assert store.save()
        kept = path.read_text()
        guard.admit((7, "shaketable/t/controller/command"), 11 * S)

        def full(*_: object) -> None:
            raise OSError(28, "No space left on device")

        monkeypatch.setattr(os, "replace", full)  # the disk fills between the temporary file and the rename
        assert not store.save() and store.errors == 1
        assert path.read_text() == kept and sorted(p.name for p in tmp_path.iterdir()) == [path.name]
        monkeypatch.undo()
        assert store.save()
    finally:
        store.close()
    assert ReplayStore(path, "zenoh").load() == guard.state()


@pytest.mark.parametrize(("text", "message"), [
    ("{", "line 1: not JSON"),
    ('{"format": "other"}', "format: expected 'shaketable-rig/replay-state/1'"),
    ('{"format": "F", "transport": "zenoh", "current": 0, "streams": []}', "transport: the state of a 'zenoh'"),
    ('{"format": "F", "transport": "mavlink", "current": -1, "streams": []}', "current: expected an integer stamp"),
    ('{"format": "F", "transport": "mavlink", "current": 281474976710656, "streams": []}', "current: expected"),
    ('{"format": "F", "transport": "mavlink", "current": 1.5, "streams": []}', "current: expected"),
    ('{"format": "F", "transport": "mavlink", "current": 1, "streams": {}}', "streams: expected a list"),
    ('{"format": "F", "transport": "mavlink", "current": 1, "streams": [[[0, 1, 256], 5]]}',
     "streams[0]: expected [link id, system, component], each 0..255"),
    ('{"format": "F", "transport": "mavlink", "current": 1, "streams": [[[0, 1, 1], 5], [[0, 1, 2]]]}',
     "streams[1]: expected [stream, stamp]"),
    ('{"format": "F", "transport": "mavlink", "current": 1, "streams": [[[0, 1, 1], true]]}',
     "streams[0]: expected an integer stamp"),
])
def test_a_damaged_state_file_is_refused_with_its_name_and_field(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "replay.json"
    path.write_text(text.replace('"F"', json.dumps(FORMAT)))
    with pytest.raises(ReplayStateError) as err:
        ReplayStore(path, "mavlink").load()
    assert str(err.value).startswith(f"replay state {path}: ") and message in str(err.value)
    assert "\n" not in str(err.value)
