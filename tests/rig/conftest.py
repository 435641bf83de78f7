"""Fixtures of the rig's tests (sessions, sequences, orchestrator, CLI, service, console)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.sequence import Sequence, load_sequence
from tests.helpers.sequences import TINY


@pytest.fixture
def tiny(tmp_path: Path) -> Sequence:
    """The tiny sequence (two short records at 0°, one Table V body) as a file of this test's folder, read."""
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    return load_sequence(path)
