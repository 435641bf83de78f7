"""Issue 42 item 5: a table belongs to one host at a time (``docs/table-controller.md``, One host at a time).

Two hosts (two driver instances, the same key) against one emulator per transport: the second is refused at
connect with "table in use by … since …" while the first streams, and the first never notices (its stream and its
next run play in full); once the first closes (RELEASE) or falls silent (killed), the second claims the table.
Real emulator processes (the session's shared one per transport, at rest before each test:
``tests/helpers/tables.py``) and sockets; no mocks.
"""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from drivers.controller import TableInUseError, open_table
from sim_table.ownership import OWNER_TIMEOUT
from tests.helpers.owner import owner_streaming
from tests.helpers.streams import there_and_back
from tests.helpers.tables import SharedTable

pytestmark = pytest.mark.integration  # starts processes and opens sockets (tests/conftest.py)

IN_USE = r"table in use by .+ since \d{4}-\d\d-\d\d \d\d:\d\d:\d\d UTC"


@pytest.mark.parametrize("transport", ["mavlink", "zenoh"])
def test_a_second_host_is_refused_and_the_first_never_notices(transport: str, shared_table: SharedTable) -> None:
    emulator, key_file = shared_table.emulator, shared_table.key_file
    try:
        with open_table(emulator.url, key_file=str(key_file)) as first:
            with owner_streaming(first, 3.0):  # the first host's run plays in full
                second = open_table(emulator.url, key_file=str(key_file))
                with pytest.raises(TableInUseError, match=IN_USE) as refused:
                    second.connect()
                assert first.status().state == "streaming"  # the refusal changed nothing

            again = first.stream(*there_and_back(3.0))  # the first host's next run
            assert again.underruns == 0 and again.final is not None and again.final.state == "armed"
            first.disarm()
    finally:
        counters = shared_table.counters()
    message = str(refused.value)
    assert message.startswith(emulator.url) and "last heard" in message
    if transport == "mavlink":
        assert "(system 255, component 190)" in message
    assert counters["link"]["claims_refused"] == 1
    assert counters["watchdog_stops"] == 0 and counters["streams_completed"] == 2


@pytest.mark.parametrize("transport", ["mavlink", "zenoh"])
def test_the_table_is_free_once_its_owner_releases_it(transport: str, shared_table: SharedTable) -> None:
    emulator, key_file = shared_table.emulator, shared_table.key_file
    try:
        with open_table(emulator.url, key_file=str(key_file)) as first:
            first.arm()
            first.disarm()
        with open_table(emulator.url, key_file=str(key_file)) as second:  # at once: released on close
            second.arm()
            second.disarm()
    finally:
        counters = shared_table.counters()
    assert counters["link"]["claims_granted"] == 2 and counters["link"]["claims_refused"] == 0


HOST_SCRIPT = textwrap.dedent("""
    import sys, time
    from drivers.controller import open_table

    table = open_table(sys.argv[1], key_file=sys.argv[2])
    table.connect()
    print("claimed", flush=True)
    time.sleep(600)
""")


@pytest.mark.parametrize("transport", ["mavlink", "zenoh"])
def test_a_silent_owner_loses_its_claim(transport: str, shared_table: SharedTable) -> None:
    emulator, key_file = shared_table.emulator, shared_table.key_file
    host = subprocess.Popen([sys.executable, "-c", HOST_SCRIPT, emulator.url, str(key_file)],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert host.stdout is not None and host.stdout.readline().strip() == "claimed"
        host.kill()  # no RELEASE: the owner falls silent
        host.wait(10)
        silent_since = time.monotonic()
        with pytest.raises(TableInUseError, match=IN_USE):
            open_table(emulator.url, key_file=str(key_file)).connect()
        time.sleep(max(0.0, silent_since + OWNER_TIMEOUT + 0.3 - time.monotonic()))
        with open_table(emulator.url, key_file=str(key_file)) as second:
            second.arm()
            second.disarm()
    finally:
        if host.poll() is None:
            host.kill()
            host.wait(10)
        counters = shared_table.counters()
    assert counters["link"]["claim_takeovers"] == 1


FROZEN_SCRIPT = textwrap.dedent("""
    import sys
    from drivers.controller import TableError, open_table

    with open_table(sys.argv[1], key_file=sys.argv[2]) as table:
        print("claimed", flush=True)
        sys.stdin.readline()  # frozen (SIGSTOP) meanwhile, then woken
        try:
            table.arm()
            print("armed", flush=True)
        except TableError as exc:
            print(exc, flush=True)
""")


@pytest.mark.parametrize("transport", ["mavlink", "zenoh"])
def test_a_host_frozen_past_the_timeout_finds_the_table_taken_and_is_told_by_whom(
        transport: str, shared_table: SharedTable) -> None:
    emulator, key_file = shared_table.emulator, shared_table.key_file
    host = subprocess.Popen([sys.executable, "-c", FROZEN_SCRIPT, emulator.url, str(key_file)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert host.stdin is not None and host.stdout is not None
        assert host.stdout.readline().strip() == "claimed"
        host.send_signal(signal.SIGSTOP)  # alive, but silent
        time.sleep(OWNER_TIMEOUT + 0.3)
        with open_table(emulator.url, key_file=str(key_file)) as second:
            second.arm()
            host.send_signal(signal.SIGCONT)
            host.stdin.write("go\n")
            host.stdin.flush()
            answer = host.stdout.readline().strip()
            assert second.status().state == "armed"  # the woken host changed nothing
            second.disarm()
        host.wait(20)
    finally:
        if host.poll() is None:
            host.send_signal(signal.SIGCONT)
            host.kill()
            host.wait(10)
        counters = shared_table.counters()
    assert re.fullmatch(r"ARM refused: " + IN_USE + r".*", answer), answer
    assert counters["link"]["claim_takeovers"] == 1 and counters["link"]["commands_other_host"] == 1
