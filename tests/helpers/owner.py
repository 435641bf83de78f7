"""A host that owns a table and plays a run in a thread of its own while the test, beside it, stands for another
host (a refused connect, a ``rig table check``): the setup the table-owner and table-check tests share."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager

from drivers.controller import StreamReport, TableController
from tests.helpers.streams import there_and_back

JOIN_S = 60.0
"""How long the owner's run may take to end once the ``with`` body is done [s] (never reached when it works)."""


@contextmanager
def owner_streaming(owner: TableController, duration: float) -> Iterator[None]:
    """``owner`` (connected) arms its table and plays :func:`there_and_back` of ``duration`` s in a thread of its own;
    the ``with`` body runs once the table streams. Then the run must have played in full: one report, no underrun,
    the table armed after it with no fault."""
    owner.arm()
    t, poses = there_and_back(duration)
    reports: list[StreamReport] = []
    errors: list[BaseException] = []

    def play() -> None:
        try:
            reports.append(owner.stream(t, poses))
        except BaseException as exc:  # handed to the test's thread
            errors.append(exc)

    streaming = threading.Thread(target=play)
    streaming.start()
    try:
        owner.wait_for_state("streaming", 10)
        yield
    finally:
        streaming.join(JOIN_S)
    assert not errors and len(reports) == 1, errors
    assert reports[0].underruns == 0 and reports[0].final is not None
    assert reports[0].final.state == "armed" and not reports[0].final.faults
