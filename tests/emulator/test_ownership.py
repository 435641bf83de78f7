"""The table's owner (``sim_table.ownership``): claims, silence, release, who may command motion. In-process."""

from __future__ import annotations

import pytest

from sim_table.ownership import Ownership

S = 1_000_000_000  # ns


def test_the_first_claim_wins_and_the_second_host_is_told_who_and_since_when() -> None:
    owners = Ownership(3 * S)
    assert owners.claim("a", "host A", 10 * S, 1_700_000_000.0) is None
    held = owners.claim("b", "host B", 11 * S, 1_700_000_001.0)
    assert held is not None and (held.who, held.description, held.since_unix_s) == ("a", "host A", 1_700_000_000.0)
    assert owners.allows("a", 11 * S) and not owners.allows("b", 11 * S)
    assert owners.claim("a", "host A", 12 * S, 1_700_000_002.0) is None  # a renewal keeps the original time
    owner = owners.owner(12 * S)
    assert owner is not None and owner.since_unix_s == 1_700_000_000.0
    assert (owners.claims_granted, owners.claims_refused, owners.takeovers) == (1, 1, 0)


def test_the_owners_messages_keep_its_claim_and_silence_ends_it() -> None:
    owners = Ownership(3 * S)
    owners.claim("a", "host A", 0, 0.0)
    assert owners.heard("a", 2 * S) and not owners.heard("b", 2 * S)
    assert owners.claim("b", "host B", 5 * S, 5.0) is not None  # heard 3 s ago: still the owner
    assert owners.owner(5 * S + 1) is None and owners.allows("b", 5 * S + 1)  # silent longer than the timeout
    assert not owners.heard("a", 5 * S + 1)  # a silent owner's heartbeat does not revive its claim
    assert owners.claim("b", "host B", 5 * S + 1, 6.0) is None
    assert owners.takeovers == 1 and not owners.allows("a", 5 * S + 2)


def test_only_the_owner_releases_the_table() -> None:
    owners = Ownership(3 * S)
    owners.claim("a", "host A", 0, 0.0)
    assert not owners.release("b", S) and owners.owner(S) is not None
    assert owners.release("a", S) and owners.owner(S) is None
    assert owners.release("b", S)  # nobody owns it: nothing to refuse
    assert owners.claim("b", "host B", S, 1.0) is None and owners.takeovers == 0


def test_a_timeout_must_be_positive() -> None:
    with pytest.raises(ValueError, match="timeout_ns must be > 0"):
        Ownership(0)
