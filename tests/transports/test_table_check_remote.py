"""``rig table check URL`` on MAVLink and zenoh tables (issue 36 item 5): what the table is as its controller
reports it, and whether it can be driven — observed, never claimed (``observe=True``), so a check on a table
another host owns leaves that host's run undisturbed.

The session's shared emulator per transport (``tests/transports/conftest.py``, at rest before each test); the
command in-process (``tests.helpers.cli.rig``) on an idle table; beside an owner (a driver in this process) as a
process of its own, the other host it stands for.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

from drivers.controller import open_table
from tests.helpers.cli import rig
from tests.helpers.owner import owner_streaming
from tests.helpers.processes import RIG, ROOT
from tests.helpers.streams import there_and_back
from tests.helpers.tables import SharedTable

pytestmark = pytest.mark.integration  # opens sockets to emulator processes (tests/conftest.py)


@pytest.mark.parametrize("transport", ["mavlink", "zenoh"])
def test_table_check_reports_an_idle_table_as_drivable_without_claiming_it(transport: str,
                                                                           shared_table: SharedTable) -> None:
    try:
        as_json = rig("table", "check", shared_table.url, "--key-file", str(shared_table.key_file), "--json")
        text = rig("table", "check", shared_table.url, "--key-file", str(shared_table.key_file))
    finally:
        counters = shared_table.counters()
    assert as_json.exit_code == 0, as_json.output
    report = json.loads(as_json.stdout)
    assert report["drivable"] is True and report["transport"] == transport and report["claimed"] is False
    assert report["status"]["state"] == "idle" and report["status"]["faults"] == []
    assert max(abs(v) for v in report["status"]["pose"]) < 1e-4 and report["status"]["buffer_capacity"] > 0
    assert "in_use" not in report and isinstance(report["link"], dict)
    assert text.exit_code == 0, text.output
    said = " ".join(text.stdout.split())
    assert f"{transport} table {shared_table.url}: state idle, faults none, pose at home" in said, said
    assert "observed without claiming it" in said and said.endswith("the table can be driven"), said
    assert counters["link"]["claims_granted"] == 0 and counters["link"]["claims_refused"] == 0


def check_as_another_host(url: str, key_file: Path, *options: str) -> subprocess.CompletedProcess[str]:
    """``rig table check URL`` as a process of its own: another host beside the owner in this process (nothing of
    it shares this interpreter with the owner's stream)."""
    return subprocess.run([*RIG, "table", "check", url, "--key-file", str(key_file), *options], cwd=ROOT,
                          capture_output=True, text=True, env={**os.environ, "COLUMNS": "160"}, check=False)


@pytest.mark.parametrize("transport", ["mavlink", "zenoh"])
def test_table_check_on_a_table_another_host_streams_observes_and_the_run_plays_in_full(
        transport: str, shared_table: SharedTable) -> None:
    """A host owns the table and streams a 12 s run; ``rig table check`` (its own process) meanwhile reports it in
    use (streaming), exit 3, without claiming it (no claim granted or refused but the owner's), and again once the
    owner holds it armed; the owner's run and its next one play in full, no underrun, no watchdog stop."""
    emulator, key_file = shared_table.emulator, shared_table.key_file
    try:
        with open_table(emulator.url, key_file=str(key_file)) as owner:
            with owner_streaming(owner, 12.0):  # the owner's run plays in full
                checked = check_as_another_host(emulator.url, key_file, "--json")
                streaming_after = owner.status().state
            armed = check_as_another_host(emulator.url, key_file)
            again = owner.stream(*there_and_back(2.0))  # the owner's next run
            assert again.underruns == 0 and again.final is not None and again.final.state == "armed"
            owner.disarm()
    finally:
        counters = shared_table.counters()
    assert checked.returncode == 3, checked.stdout + checked.stderr
    report = json.loads(checked.stdout)
    assert streaming_after == "streaming"  # the check changed nothing
    assert report["drivable"] is False and report["claimed"] is False and report["transport"] == transport
    assert report["status"]["state"] == "streaming" and report["in_use"].startswith("streaming: a host is playing")
    assert armed.returncode == 3, armed.stdout + armed.stderr
    said = " ".join(armed.stdout.split())
    assert "state armed" in said and "in use: armed: a host has armed it" in said, said
    assert said.endswith("the table cannot be driven now"), said
    assert counters["link"]["claims_granted"] == 1 and counters["link"]["claims_refused"] == 0
    assert counters["watchdog_stops"] == 0 and counters["streams_completed"] == 2
