"""The link's heap hold (drivers/heap.py): what it freezes, when it lets go, and that every link holds it."""

from __future__ import annotations

import gc
import weakref

import pytest

from drivers.controller import open_table
from drivers.heap import HeapHold
from tests.helpers.tables import SharedTable


class Node:
    """A container that can take part in a reference cycle and be watched by a weak reference."""

    def __init__(self) -> None:
        self.other: Node | None = None


def cycle() -> tuple[weakref.ref[Node], Node]:
    a, b = Node(), Node()
    a.other, b.other = b, a
    return weakref.ref(a), a


def tracked(obj: object) -> bool:
    """Whether the collector's generations (not the permanent one) hold ``obj``."""
    return any(o is obj for o in gc.get_objects())


@pytest.fixture(autouse=True)
def nothing_frozen() -> None:
    assert gc.get_freeze_count() == 0, "a link of another test was left open"


def test_a_hold_freezes_the_heap_and_the_last_release_hands_it_back() -> None:
    before = Node()
    first, second = HeapHold(), HeapHold()
    first.hold()
    assert first.held and gc.get_freeze_count() > 0 and not tracked(before)
    made_while_held = Node()
    assert tracked(made_while_held)  # made since: a full pass visits it
    second.hold()  # refreezes what was made since
    assert not tracked(made_while_held)
    first.release()
    first.release()  # idempotent: does not count the other holder out
    assert gc.get_freeze_count() > 0 and not tracked(before)
    second.release()
    assert gc.get_freeze_count() == 0 and tracked(before) and tracked(made_while_held)


def test_a_frozen_cycle_is_freed_after_the_release_a_cycle_made_while_held_at_once() -> None:
    frozen_ref, frozen = cycle()
    hold = HeapHold()
    hold.hold()
    try:
        del frozen
        young_ref, young = cycle()
        del young
        gc.collect()
        assert frozen_ref() is not None  # the documented cost: frozen garbage waits for the release
        assert young_ref() is None
    finally:
        hold.release()
    gc.collect()
    assert frozen_ref() is None


@pytest.mark.integration  # opens a link to the shared emulator (tests/conftest.py)
def test_a_mavlink_link_holds_the_heap_from_connect_to_close(shared_mavlink_table: SharedTable) -> None:
    table = open_table(shared_mavlink_table.url, key_file=str(shared_mavlink_table.key_file))
    before = Node()
    with table:
        assert table.heap.held and gc.get_freeze_count() > 0 and not tracked(before)
        table.arm()
        table.disarm()
    assert not table.heap.held and gc.get_freeze_count() == 0 and tracked(before)
    counters = shared_mavlink_table.counters()
    assert counters["state"] == "idle" and counters["commands_accepted"] >= 2, counters
