"""The commit-msg hook `make` enables: a subject over 72 characters is refused, one of 72 (multi-byte too) taken."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

HOOK = Path(__file__).resolve().parents[1] / ".githooks" / "commit-msg"

pytestmark = pytest.mark.integration  # runs the hook as a process (tests/conftest.py)


def hook(tmp_path: Path, message: str) -> subprocess.CompletedProcess[str]:
    path = tmp_path / "COMMIT_EDITMSG"
    path.write_text(message, encoding="utf-8")
    return subprocess.run([str(HOOK), str(path)], capture_output=True, text=True, check=False)


@pytest.mark.parametrize("subject", ["a" * 72, "é" * 72, "short"])
def test_a_subject_of_at_most_72_characters_is_taken(tmp_path: Path, subject: str) -> None:
    body = "the details, as long as they need to be " * 5
    assert hook(tmp_path, f"# a comment git adds\n{subject}\n\n{body}\n").returncode == 0


def test_a_longer_subject_is_refused_with_its_length(tmp_path: Path) -> None:
    done = hook(tmp_path, "b" * 73 + "\n\nbody\n")
    assert done.returncode == 1
    assert "the subject is 73 characters (at most 72" in done.stderr
