"""Fixtures of the transport tests: one emulated table per transport shared by the session
(``tests/helpers/tables.py``), brought back to rest and checked before each test that takes it."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.helpers.tables import SharedTable, start_shared_table


def _session_table(transport: str, key_file: Path) -> Iterator[SharedTable]:
    table = start_shared_table(transport, key_file)
    try:
        yield table
    finally:
        table.emulator.stop()


@pytest.fixture(scope="session")
def _mavlink_session_table(shared_key_file: Path) -> Iterator[SharedTable]:
    yield from _session_table("mavlink", shared_key_file)


@pytest.fixture(scope="session")
def _zenoh_session_table(shared_key_file: Path) -> Iterator[SharedTable]:
    yield from _session_table("zenoh", shared_key_file)


@pytest.fixture
def shared_mavlink_table(_mavlink_session_table: SharedTable) -> SharedTable:
    """The session's MAVLink emulator (real time, no bodies), at rest and checked so (``tests/helpers/tables.py``)."""
    _mavlink_session_table.rest()
    _mavlink_session_table.tests_served += 1
    return _mavlink_session_table


@pytest.fixture
def shared_zenoh_table(_zenoh_session_table: SharedTable) -> SharedTable:
    """The session's zenoh emulator (real time, no bodies), at rest and checked so (``tests/helpers/tables.py``)."""
    _zenoh_session_table.rest()
    _zenoh_session_table.tests_served += 1
    return _zenoh_session_table


@pytest.fixture
def shared_table(request: pytest.FixtureRequest) -> SharedTable:
    """The shared table of the test's ``transport`` parameter (``mavlink`` or ``zenoh``)."""
    transport = request.node.callspec.params["transport"]
    table: SharedTable = request.getfixturevalue(f"shared_{transport}_table")
    return table
