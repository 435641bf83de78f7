"""Limit detectors on the emulated table in virtual time (the session's table with the sequence's bodies,
``body_table``, rested between tests; an emulator of its own where a fault is injected), MAVLink over loopback UDP:
an abort level on the plate's acceleration, downloaded to the controller (MAVLink and zenoh), stops the table within
one status period of the crossing in the table's time and ends the run ``aborted: limit accel.0.x`` with the
controller's trip event and the data up to it kept, and the controller's persistence of N ignores shorter spikes;
the host's detectors alone (the fallback) also stop it, later; a warning level only records; a persistence of N
on the host ignores shorter excursions and trips on the N-th sample in a row; levels on the plate's pose and on a
leg's following error also trip on the controller, on the status that completes the persistence, and stop the
table within one status period."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from drivers.chunked import AHEAD_NS
from rig.orchestrator import OrchestratorState
from rig.sequence import Sequence, load_sequence
from rig.session import read_session
from sim_table.process import STATUS_PERIOD_NS
from tests.helpers.sequences import TINY_ONE_RUN, new_log, play, play_on
from tests.helpers.tables import LISTEN, SharedTable

pytestmark = pytest.mark.integration  # starts processes or opens sockets (tests/conftest.py)

BodyTable = Callable[..., SharedTable]
"""The ``body_table`` fixture (``tests/rig/conftest.py``)."""


def sequence(tmp_path: Path, levels: str, channel: str = "accel.x") -> Sequence:
    path = tmp_path / "limits.toml"
    path.write_text(f"{TINY_ONE_RUN}\n[limit_detectors.{channel}]\n{levels}\n")
    return load_sequence(path)


def play_into(sequence: Sequence, path: Path, body_table: BodyTable, key_file: Path, *flags: str,
              controller_limits: bool = True, transport: str = "mavlink"
              ) -> tuple[OrchestratorState, dict[str, Any], dict[str, Any]]:
    """The sequence played into ``path`` on the session's table with its bodies on ``transport`` (``body_table``),
    or with ``flags`` (fault injection) on a fresh emulator of its own: the final state, the emulator's counters, the
    run (``controller_limits`` False: the host's detectors act alone)."""
    log = new_log(sequence, path)
    options = {"controller_limits": controller_limits}
    try:
        if flags:
            state, counters = play(sequence, log, key_file, emulator_flags=flags, listen=LISTEN[transport],
                                   orchestrator_options=options)
        else:
            state, counters = play_on(body_table(sequence, transport), sequence, log, orchestrator_options=options)
    finally:
        log.close()
    [run] = read_session(path)["runs"]
    return state, counters, run


def crossing(run: dict[str, Any], level: float) -> float:
    """The time of the first sample of accelerometer 0 whose x is above ``level`` [m/s²]."""
    accel = run["accel"]["0"]
    return float(accel[np.argmax(accel[:, 1] > level), 0])


def nth_in_a_row(run: dict[str, Any], level: float, n: int) -> float:
    """The time of the ``n``-th sample in a row of accelerometer 0's x above ``level`` [m/s²] in its first excursion
    that long, after shorter ones (what a persistence of ``n`` ignores)."""
    accel = run["accel"]["0"]
    past = np.concatenate([[False], accel[:, 1] > level])
    starts = np.flatnonzero(~past[:-1] & past[1:])  # where each excursion past the level begins
    ends = np.flatnonzero(past[:-1] & ~past[1:])
    lengths = np.append(ends, len(accel))[:len(starts)] - starts
    assert lengths[0] < n  # the first excursions are short spikes: ignored
    first_long = starts[np.argmax(lengths >= n)]
    return float(accel[first_long + n - 1, 0])


def stop_latency_ms(run: dict[str, Any], source: str, channel: str = "accel.0.x") -> float:
    """The run's event timing the stop after a trip found by ``source`` [ms, table time]."""
    [stopped] = [event["text"] for event in run["events"]
                 if f"ms after the crossing (table time; tripped by the {source})" in event["text"]]
    assert stopped.startswith(f"limit {channel}: the table was stopping ")
    return float(stopped.split(" was stopping ")[1].split(" ms ")[0])


@pytest.mark.parametrize("transport", ["mavlink", "zenoh"])
def test_the_controller_stops_within_one_status_period_of_the_crossing(tmp_path: Path, body_table: BodyTable,
                                                                       key_file: Path, transport: str) -> None:
    state, counters, run = play_into(sequence(tmp_path, "abort_high_g = 0.05"), tmp_path / "s.h5", body_table,
                                     key_file, transport=transport)
    assert state is OrchestratorState.DONE  # a controlled stop: the table is left home and armed, not faulted
    assert run["status"] == "aborted" and run["attrs"]["reason"].startswith("limit accel.0.x: ")
    assert counters["limit_trips"] == 1 and counters["emergency_stops"] == 0 and counters["streams_completed"] == 0
    texts = [event["text"] for event in run["events"]]
    assert "limit detectors on the controller: accel.x abort high 0.4905 m/s²" in texts
    [trip] = [event for event in run["events"] if event["text"].endswith("controlled_stop (controller)")]
    t_cross = crossing(run, 0.05 * 9.81)
    assert trip["t"] == pytest.approx(t_cross)  # the first sample past the level, as the host has it
    assert trip["text"].startswith("limit accel.0.x: ") and "past abort high 0.4905 m/s²" in trip["text"]
    assert 0 < stop_latency_ms(run, "controller") <= STATUS_PERIOD_NS * 1e-6  # the goal, in the table's time
    accel = run["accel"]["0"]
    assert accel[0, 0] < t_cross < accel[-1, 0]  # the data up to the trip (and the stop after it) kept


def test_the_controller_ignores_a_spike_shorter_than_the_persistence(tmp_path: Path, body_table: BodyTable,
                                                                    key_file: Path) -> None:
    state, _, run = play_into(sequence(tmp_path, "abort_high_g = 0.05\npersistence = 25"), tmp_path / "s.h5",
                              body_table, key_file)
    assert state is OrchestratorState.DONE and run["status"] == "aborted"
    [trip] = [event for event in run["events"] if event["text"].endswith("controlled_stop (controller)")]
    assert trip["t"] == pytest.approx(nth_in_a_row(run, 0.05 * 9.81, 25))
    assert 0 < stop_latency_ms(run, "controller") <= STATUS_PERIOD_NS * 1e-6


def test_the_host_alone_stops_the_table_and_keeps_the_data(tmp_path: Path, body_table: BodyTable,
                                                           key_file: Path) -> None:
    limited = sequence(tmp_path, "abort_high_g = 0.05")
    state, counters, run = play_into(limited, tmp_path / "s.h5", body_table, key_file, controller_limits=False)
    assert state is OrchestratorState.DONE  # a controlled stop: the table is left home and armed, not faulted
    assert run["status"] == "aborted"
    assert run["attrs"]["reason"].startswith("limit accel.0.x: ")
    assert counters["stops"] == 1 and counters["emergency_stops"] == 0 and counters["streams_completed"] == 0
    texts = [event["text"] for event in run["events"]]
    [trip] = [event for event in run["events"] if event["text"].startswith("limit accel.0.x: ")
              and "past abort high" in event["text"]]
    t_cross = crossing(run, 0.05 * 9.81)
    assert trip["t"] == pytest.approx(t_cross)  # the trip is the first sample past the level
    assert trip["text"].endswith("past abort high 0.4905 m/s²: controlled_stop (host)")
    assert [text for text in texts if text.startswith("limit detectors on the host only (host only, as asked)")]
    latency_ms = stop_latency_ms(run, "host")
    # In virtual time the emulator runs ahead of the host up to the setpoints it holds (the lead and the driver's
    # AHEAD_NS beyond its last status), and takes a host message at its next batch of ticks: that bounds how far
    # the table runs past the crossing before a host-side detector's stop. (The goal, one status period, is
    # measured by benchmarks/limits.py; docs/limits.md says why it is not met host-side.)
    bound_ms = (limited.table.link.lead_s + (AHEAD_NS + STATUS_PERIOD_NS) * 1e-9) * 1e3
    assert 0 < latency_ms <= bound_ms
    accel = run["accel"]["0"]
    assert accel[0, 0] < t_cross < accel[-1, 0]  # the data up to the trip (and the stop after it) kept
    assert accel[-1, 0] < run["commanded"][-1, 0] - 0.5  # the drive did not play to its end


def test_a_warning_level_only_records(tmp_path: Path, body_table: BodyTable, key_file: Path) -> None:
    state, counters, run = play_into(sequence(tmp_path, "warn_high_g = 0.05\nwarn_low_g = -0.05"), tmp_path / "s.h5",
                                     body_table, key_file)
    assert state is OrchestratorState.DONE
    assert run["status"] == "completed"
    assert counters["stops"] == 0 and counters["streams_completed"] == 1
    trips = {event["text"].split(" past ")[1].rsplit(" ", 3)[0]: event for event in run["events"]
             if event["text"].startswith("limit accel.0.x: ")}
    assert sorted(trips) == ["warn high 0.4905", "warn low -0.4905"]
    assert all(event["text"].endswith(": record (host)") for event in trips.values())
    accel = run["accel"]["0"]
    assert trips["warn high 0.4905"]["t"] == pytest.approx(crossing(run, 0.05 * 9.81))
    assert trips["warn low -0.4905"]["t"] == pytest.approx(float(accel[np.argmax(accel[:, 1] < -0.05 * 9.81), 0]))


def test_a_persistence_of_n_ignores_shorter_excursions(tmp_path: Path, body_table: BodyTable, key_file: Path) -> None:
    state, _, run = play_into(sequence(tmp_path, "warn_high_g = 0.05\npersistence = 25"), tmp_path / "s.h5",
                              body_table, key_file)
    assert state is OrchestratorState.DONE and run["status"] == "completed"
    [trip] = [event for event in run["events"] if event["text"].startswith("limit accel.0.x: ")]
    assert trip["t"] == pytest.approx(nth_in_a_row(run, 0.05 * 9.81, 25))


@pytest.mark.parametrize("transport", ["mavlink", "zenoh"])
def test_a_stalled_leg_trips_its_following_error_on_the_controller(tmp_path: Path, body_table: BodyTable,
                                                                    key_file: Path, transport: str) -> None:
    limited = sequence(tmp_path, "abort_high_mm = 5\nabort_low_mm = -5\npersistence = 2", "leg.following_error")
    state, counters, run = play_into(limited, tmp_path / "s.h5", body_table, key_file, "--leg-stall", "2@0.5",
                                     transport=transport)
    assert run["status"] == "aborted" and run["attrs"]["reason"].startswith("limit leg.2.following_error: ")
    assert state is OrchestratorState.DONE and counters["limit_trips"] == 1
    texts = [event["text"] for event in run["events"]]
    assert [text for text in texts if text.startswith("limit detectors on the controller: leg.following_error ")]
    trips = {event["text"].rsplit(" ", 1)[1]: event for event in run["events"]
             if event["text"].startswith("limit leg.2.following_error: ") and " past abort " in event["text"]}
    assert trips["(controller)"]["text"].endswith(": controlled_stop (controller)")
    value = float(trips["(controller)"]["text"].split(": ")[1].split(" m past")[0])
    assert abs(value) > 0.005
    assert 0.5 < trips["(controller)"]["t"] < run["commanded"][-1, 0]  # after the leg seized (0.5 s), mid-run
    if "(host)" in trips:  # the backup: the same status, when the host saw it before the stream ended
        assert trips["(host)"]["t"] == pytest.approx(trips["(controller)"]["t"])
    errors = run["following_error"]  # the series the trip is on, stored: (t, legs 1…6) [s, m]
    past = np.abs(errors[:, 2]) > 0.005
    second = np.flatnonzero(past[1:] & past[:-1])[0] + 1  # the second status in a row past the level
    assert trips["(controller)"]["t"] == pytest.approx(float(errors[second, 0]))
    assert 0 < stop_latency_ms(run, "controller", "leg.2.following_error") <= STATUS_PERIOD_NS * 1e-6


def test_a_pose_level_trips_on_the_controller_within_one_status_period(tmp_path: Path, body_table: BodyTable,
                                                                       key_file: Path) -> None:
    state, counters, run = play_into(sequence(tmp_path, "abort_high_mm = 2\nabort_low_mm = -2", "pose.surge"),
                                     tmp_path / "s.h5", body_table, key_file)
    assert state is OrchestratorState.DONE and counters["limit_trips"] == 1
    assert run["status"] == "aborted" and run["attrs"]["reason"].startswith("limit pose.surge: ")
    [trip] = [event for event in run["events"]
              if event["text"].startswith("limit pose.surge: ") and event["text"].endswith(" (controller)")]
    assert " m past abort " in trip["text"]
    pose = run["pose"]
    first = int(np.argmax(np.abs(pose[:, 1]) > 0.002))  # the first status past a level, as the host has it
    assert trip["t"] == pytest.approx(float(pose[first, 0]))
    assert 0 < stop_latency_ms(run, "controller", "pose.surge") <= STATUS_PERIOD_NS * 1e-6
