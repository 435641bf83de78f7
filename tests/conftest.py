"""Shared fixtures of the physics tests (kept small on purpose)."""

from __future__ import annotations

import pytest

from analysis import Body


@pytest.fixture
def v_body() -> Body:
    """The VALIDATION.md block: p = 2 rad/s, α = 0.2 rad (b ≈ 0.729 m, h ≈ 3.61 m)."""
    return Body.from_p_alpha(2.0, 0.2)
