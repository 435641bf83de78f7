"""One emulated table shared by the tests of a session, brought back to rest between two tests.

A test that only needs *a* table (not its own process lifetime, a kill, a port, a key or emulator options of its
own) takes the ``shared_mavlink_table`` or ``shared_zenoh_table`` fixture (``tests/transports/conftest.py``): one
emulator process per transport for the whole session (per xdist worker under ``-n``; the integration tier runs one
at a time, so one in all), at real time, no bodies, signed with a key of its own. Before each test it is brought
back to its power-up state (``EmulatorProcess.rest``: at home, idle, no fault, no owner, counters zero; the signing
replay guard kept) and :func:`check_at_rest` looks at it over the link, as the test will; the test then reads what
it did with :meth:`SharedTable.counters` (the counters :meth:`rig.emulator.EmulatorProcess.stop` would have
returned had the emulator been its own). A test that plays a sequence takes a table with its bodies on the plate, in
virtual time, from a :class:`TablePool` (``body_table``, ``tests/rig/conftest.py``): one per set of bodies.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drivers.controller import open_table
from rig.emulator import EmulatorProcess

LISTEN = {"mavlink": "mavlink://127.0.0.1:0", "zenoh": "zenoh://127.0.0.1:0/table"}

AT_HOME = 1e-4
"""How far from home a table at rest may be measured [m on the translation axes, rad on the rotation axes]: it is put
there exactly, and the measured pose carries the leg sensors' noise (a few µm); the transport tests' own "home"."""


@dataclass
class SharedTable:
    """A running emulator that tests take turns on: its URL, its signing key, how many tests it served."""

    transport: str
    emulator: EmulatorProcess
    key_file: Path
    flags: tuple[str, ...] = ()
    """The emulator's options (bodies, speed) beyond its listening URL and key."""
    tests_served: int = 0

    @property
    def url(self) -> str:
        return self.emulator.url

    def counters(self) -> dict[str, Any]:
        """The emulator's counters since the test began (its exit JSON object's fields); the table is brought back
        to rest as it answers, so a test calls this once, at its end."""
        return self.emulator.rest()

    def rest(self) -> None:
        """Bring the table back to its power-up state and check it is there (:func:`check_at_rest`); the look over
        the link is not counted in the next test's counters."""
        self.emulator.rest()
        check_at_rest(self)
        self.emulator.rest()


def start_shared_table(transport: str, key_file: Path, *flags: str) -> SharedTable:
    """Start the emulator a session shares on ``transport`` (``mavlink`` or ``zenoh``) with ``flags`` (none: real
    time, no bodies)."""
    return SharedTable(transport, EmulatorProcess.start(LISTEN[transport], *flags, key_file=key_file), key_file,
                       flags)


class TablePool:
    """The shared tables with bodies on the plate (``body_table`` of ``tests/rig/conftest.py``): one emulator per
    transport and set of options (the bodies and their places, the speed), started when a test first asks for it
    and brought back to rest (:meth:`SharedTable.rest`: the specimens re-seated) before each later test's turn."""

    def __init__(self, key_file: Path) -> None:
        self.key_file = key_file
        self.tables: dict[tuple[str, tuple[str, ...]], SharedTable] = {}

    def take(self, transport: str, *flags: str) -> SharedTable:
        """The table of ``transport`` with ``flags``, at rest, counters zero."""
        table = self.tables.get((transport, flags))
        if table is None:
            table = self.tables[transport, flags] = start_shared_table(transport, self.key_file, *flags)
        else:
            table.rest()
        table.tests_served += 1
        return table

    def stop(self) -> None:
        """Stop every table started (the first failure raised once all were asked to stop)."""
        tables = list(self.tables.values())
        self.tables.clear()
        errors = []
        for table in tables:
            try:
                table.emulator.stop()
            except Exception as error:  # the others must still stop
                errors.append(error)
        if errors:
            raise errors[0]


def check_at_rest(table: SharedTable) -> None:
    """Fail unless the table, seen over its link by a host that only listens, is idle at home with no fault, no
    underrun, no refused command and an empty buffer: a test must not inherit another's state."""
    exit_code = table.emulator.exit_code
    assert exit_code is None, f"the shared {table.transport} emulator exited ({exit_code})"
    options: dict[str, Any] = {"observe": True, **({"system": 254} if table.transport == "mavlink" else {})}
    with open_table(table.url, key_file=str(table.key_file), **options) as observer:
        status = observer.wait_for_status(lambda _: True, 10)
    assert status.state == "idle" and not status.faults, f"shared {table.transport} table not at rest: {status}"
    assert status.underruns == 0 and status.refused_commands == 0 and status.buffer_depth == 0, status
    assert np.abs(np.asarray(status.pose)).max() <= AT_HOME, f"shared table not at home: pose {status.pose}"
