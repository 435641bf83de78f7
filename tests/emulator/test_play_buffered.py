"""``ControllerCore.play_buffered``: a run of plain stream ticks leaves the core exactly as ``tick`` one by one does.

Two cores get the same stream and heartbeats; one ticks each tick through ``tick``, the other as the emulator's
batch does: ``play_buffered`` up to a stop, then ``tick`` for the tick it left. References, braked flags, events,
counters and the reference's state (pose, previous pose, last tick and its length, the sample played last) must
agree after every step, through samples on the tick grid, a chunk off it, a gap, an underrun-free end of stream
and a heartbeat watchdog that lapses in the middle of a run.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from analysis.table.model import TableModel
from sim_table.controller import Command, ControllerCore, Result

MS = 1_000_000


def streaming() -> ControllerCore:
    core = ControllerCore(TableModel(), watchdog_ns=100 * MS)
    core.heartbeat(0)
    assert core.command(Command.ARM, (), True, 0) is Result.ACCEPTED
    assert core.command(Command.START_STREAM, (0.0,), True, 0) is Result.ACCEPTED
    return core


def ramp(first: int, count: int) -> np.ndarray:
    """``count`` poses of a slow surge and pitch ramp from sample ``first`` (10 µm and 1 µrad a sample)."""
    k = np.arange(first, first + count, dtype=float)[:, None]
    return np.hstack([1e-5 * k, np.zeros((count, 3)), 1e-6 * k, np.zeros((count, 1))])


def state(core: ControllerCore) -> tuple[object, ...]:
    anchor = core._anchor
    return (core.state, core.faults, core._t, core._dt, core._p.tolist(), core._p_before.tolist(),
            None if anchor is None else (anchor[0], anchor[1].tolist()), core._dry, len(core._buffer),
            core.counters)


def run_both(feed: Callable[[ControllerCore, int], bool], ticks: list[int], runs: list[int]) -> int:
    """Tick ``ticks`` on two streaming cores, ``feed(core, t)`` before each tick (whether it fed anything: a host
    message); the second plays runs of at most ``runs[j]`` ticks (cycled) through ``play_buffered``, each ending
    before the next tick with a message, as the emulator's batch ends them. How many ticks it played that way."""
    one, batched = streaming(), streaming()
    fed = [feed(streaming(), t) for t in ticks]  # where the messages come, on a core of their own
    i = j = played_total = 0
    while i < len(ticks):
        feed(one, ticks[i])
        feed(batched, ticks[i])
        stop = min(len(ticks), i + runs[j % len(runs)])
        stop = next((k for k in range(i + 1, stop) if fed[k]), stop)
        j += 1
        played = batched.play_buffered(ticks, i, stop)
        for k, pose in enumerate(played):
            if k:
                assert not feed(one, ticks[i + k])
            reference, braked = one.tick(ticks[i + k])
            assert not braked
            np.testing.assert_array_equal(pose, reference)
        if played:
            i += len(played)
            played_total += len(played)
        else:
            expected = one.tick(ticks[i])
            got = batched.tick(ticks[i])
            np.testing.assert_array_equal(got[0], expected[0])
            assert got[1] == expected[1]
            i += 1
        assert batched.take_events() == one.take_events()
        assert state(batched) == state(one)
    return played_total


@pytest.mark.parametrize("runs", [[1], [3], [20], [7, 1, 13]])
@pytest.mark.parametrize("beats_until", [400 * MS, 150 * MS])
def test_runs_of_plain_stream_ticks_leave_the_core_as_ticks_one_by_one_do(runs: list[int], beats_until: int) -> None:
    """Chunks of 8 samples 1 ms apart from 21 ms, each arriving 16 to 21 ms ahead, chunk 3 missing (a gap the
    playback passes: CHUNK_GAP), chunk 5 at 2 ms spacing (between the grid's ticks: interpolated, never a plain
    tick), chunk 39 flagged END_OF_STREAM (the stream completes at 340 ms); heartbeats every 50 ms until
    ``beats_until``: 150 ms lapses the heartbeat watchdog at 251 ms, inside the stream."""
    chunks = {seq: (21 * MS + 8 * MS * seq, MS) for seq in range(40) if seq != 3}
    chunks[5] = (chunks[5][0], 2 * MS)  # 8 samples 2 ms apart: 16 ms, overlapping chunk 6's times (kept)

    def feed(core: ControllerCore, t: int) -> bool:
        beat = t % (50 * MS) == 0 and t <= beats_until
        if beat:
            core.heartbeat(t)
        seq = t // (8 * MS)
        chunk = t % (8 * MS) == 0 and seq in chunks
        if chunk:
            start, spacing = chunks[seq]
            core.chunk(seq, start, spacing, ramp(8 * seq, 8), seq == 39, True, t)
        return beat or chunk

    ticks = [k * MS for k in range(1, 400)]
    played = run_both(feed, ticks, runs)
    assert played > 150  # the runs did play most of the stream


def test_the_stream_silent_watchdog_ends_a_run_as_it_stops_a_tick() -> None:
    """Chunks stop coming after 40 ms (no END_OF_STREAM), with 200 ms of samples buffered, heartbeats every 50 ms:
    STREAM_SILENT at 141 ms, inside a run of 20."""

    def feed(core: ControllerCore, t: int) -> bool:
        if t % (50 * MS) == 0:
            core.heartbeat(t)
        if t == MS:
            core.chunk(0, 2 * MS, MS, ramp(0, 200), False, True, t)
        if t == 40 * MS:
            core.chunk(1, 202 * MS, MS, ramp(200, 8), False, True, t)
        return t % (50 * MS) == 0 or t in (MS, 40 * MS)

    assert run_both(feed, [k * MS for k in range(1, 200)], [20]) > 100
