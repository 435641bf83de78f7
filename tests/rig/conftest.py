"""Fixtures of the rig's tests (sessions, sequences, orchestrator, CLI, service, console)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from rig.sequence import Sequence, load_sequence
from tests.helpers.sequences import TINY, table_flags
from tests.helpers.tables import SharedTable, TablePool


@pytest.fixture
def tiny(tmp_path: Path) -> Sequence:
    """The tiny sequence (two short records at 0°, one Table V body) as a file of this test's folder, read."""
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    return load_sequence(path)


@pytest.fixture(scope="session")
def _body_tables(shared_key_file: Path) -> Iterator[TablePool]:
    pool = TablePool(shared_key_file)
    try:
        yield pool
    finally:
        pool.stop()


@pytest.fixture
def body_table(_body_tables: TablePool) -> Callable[..., SharedTable]:
    """``body_table(sequence, transport="mavlink")``: the session's emulated table with ``sequence``'s bodies on the
    plate, in virtual time (``tests/helpers/tables.py``, :class:`TablePool`), at rest; play on it with
    ``tests.helpers.sequences.play_on``. One emulator per set of bodies and transport, for a test that needs no
    emulator options of its own."""

    def take(sequence: Sequence, transport: str = "mavlink") -> SharedTable:
        return _body_tables.take(transport, *table_flags(sequence))

    return take
