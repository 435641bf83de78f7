"""Room on the session's disk (`rig.session.space`): what a run needs, the check before it, telling a full disk
from other errors, and `rig sessions recover` that changes nothing when it could not finish."""

from __future__ import annotations

import errno
import time
from pathlib import Path

import pytest

from rig.session import SessionError, recover, space, writer_flags
from rig.session.space import DiskFullError, check_room, is_disk_full, run_needs
from tests.helpers.session_writer import WriterChild, writer_config


def test_a_run_needs_its_rows_twice_over_and_the_reserve() -> None:
    # 10 s of drive at 1 kHz (10,001 setpoints), 2 accelerometers, 3 bodies, lingering 5 s: by hand,
    # 15 s × (2 × 2000 × 4 + 3 × 400 × 2 + 1000 × (7 + 7)) × 8 B = 15 × 32,400 × 8 = 3,888,000 B of samples
    # (the pose and the legs' following errors at every status), 10,001 × 7 × 8 = 560,056 B commanded; twice
    # that, and 16 MiB
    assert run_needs(10.0, 10_001, 2, 3) == 2 * (3_888_000 + 560_056) + 16 * 1024 * 1024


def test_the_check_refuses_below_what_is_needed_and_says_how_much(tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(space, "free_bytes", lambda path: 5 << 20)
    check_room(tmp_path / "s.h5", 5 << 20, "run 1")
    with pytest.raises(DiskFullError, match=r"^disk full: .*s\.h5: run 1 needs about 5\.0 MiB free, the file "
                                            r"system has 5\.0 MiB") as refused:
        check_room(tmp_path / "s.h5", (5 << 20) + 1, "run 1")
    assert "nothing was written" in str(refused.value)


def test_free_bytes_of_a_file_not_yet_made_is_its_directory_s(tmp_path: Path) -> None:
    assert space.free_bytes(tmp_path / "not" / "yet.h5") == space.shutil.disk_usage(tmp_path).free


def test_a_full_disk_is_told_from_other_errors() -> None:
    assert is_disk_full(OSError(errno.ENOSPC, "No space left on device"))
    assert is_disk_full(OSError(errno.EFBIG, "File too large"))  # a file size limit: no room for this file either
    assert is_disk_full(OSError("Can't write data (file write failed: ..., error message = "
                                "'[Errno 28] No space left on device', ...)"))  # h5py's text
    assert is_disk_full(RuntimeError("Unable to synchronously flush file (file write failed: ..., errno = 28, "
                                      "error message = 'No space left on device', ...)"))  # HDF5's, from a flush
    try:
        try:
            raise OSError(errno.ENOSPC, "No space left on device")
        except OSError as exc:
            raise SessionError("s.h5: run 0001: the writer failed") from exc
    except SessionError as wrapped:
        assert is_disk_full(wrapped)
    assert not is_disk_full(OSError(errno.ECONNREFUSED, "Connection refused"))
    assert not is_disk_full(SessionError("s.h5: schema attribute is 'x'"))


@pytest.mark.integration  # starts a writer process
def test_recover_on_a_full_disk_changes_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A writer killed mid-run leaves a crashed file; with less free than a recovery needs, ``recover`` refuses
    and the file keeps every byte (its writer flags too); with room, it recovers."""
    path = tmp_path / "session.h5"
    child = WriterChild(writer_config(path, tmp_path / "progress.txt", 25, sensors=2, run_seconds=(0.5, 1.0)))
    if not child.wait_marker("c", timeout=60):
        pytest.fail(f"writer never started: {child.stderr()}")
    time.sleep(0.3)
    child.kill()
    flags, content = writer_flags(path), path.read_bytes()
    assert flags != 0  # crashed: recovering it writes
    monkeypatch.setattr(space, "free_bytes", lambda where: space.RECOVER_NEEDS - 1)
    with pytest.raises(DiskFullError, match=r"^disk full: .*recovering it needs about 4\.0 MiB free"):
        recover(path)
    assert path.read_bytes() == content and writer_flags(path) == flags
    monkeypatch.undo()
    assert recover(path).changed and writer_flags(path) == 0
