"""protocols.private_file: the one reader of a private file (the rig's key, the tokens file, a TLS key) refuses a
file that is not a regular file or that others may read, naming where it came from, what it holds and the chmod."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from protocols.private_file import PrivateFileError, SharedPrivateFileError, read_private_file


def test_a_private_file_is_read_up_to_one_byte_past_the_limit(tmp_path: Path) -> None:
    path = tmp_path / "secret"
    path.write_bytes(b"x" * 10)
    path.chmod(0o600)
    assert read_private_file(path, "--secret", "the secret", 4) == b"xxxxx"
    assert read_private_file(path, "--secret", "the secret", 100) == b"x" * 10


@pytest.mark.skipif(os.name != "posix", reason="file modes are POSIX's")
def test_a_file_others_may_read_is_refused_with_the_chmod_to_run(tmp_path: Path) -> None:
    path = tmp_path / "my secret"
    path.write_bytes(b"x")
    path.chmod(0o640)
    with pytest.raises(SharedPrivateFileError) as caught:
        read_private_file(path, "--secret", "the secret", 100)
    assert str(caught.value) == f"--secret: mode 0640 lets other users read the secret; run: chmod 600 '{path}'"
    assert caught.value.mode == 0o640


def test_a_device_a_directory_and_a_missing_file_are_refused_naming_where(tmp_path: Path) -> None:
    with pytest.raises(PrivateFileError, match=r"^--secret: not a regular file$"):
        read_private_file(Path(os.devnull), "--secret", "the secret", 100)
    with pytest.raises(PrivateFileError, match=r"^--secret: Is a directory$"):
        read_private_file(tmp_path, "--secret", "the secret", 100)
    with pytest.raises(PrivateFileError, match=r"^--secret: No such file or directory$") as caught:
        read_private_file(tmp_path / "nope", "--secret", "the secret", 100)
    assert isinstance(caught.value.__cause__, FileNotFoundError)
