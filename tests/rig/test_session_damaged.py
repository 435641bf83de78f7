"""Damaged session files (issue 42, item 2): built from a real small session (truncated at several offsets, its
superblock overwritten, a metadata byte flipped, zero-filled, sparse to 4 GiB), each is refused by every tool that
opens a session file — ``rig sessions show|recover``, ``rig analyze``, ``rig report``, ``rig run --resume`` — with
one ``damaged: FILE: …`` line naming what is wrong and what ``rig sessions recover`` cannot do, exit 2, no
traceback. That it is quick is what the bounds check: HDF5's retries of a failing metadata block are bounded, and a
file no writer holds is never retried.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from pathlib import Path

import pytest
from typer.testing import CliRunner

from rig.cli import app
from rig.report.data import _open_any
from rig.session import DamagedFileError, open_session, read_session, reader
from rig.session.check import check_session
from rig.session.hdf5props import READ_ATTEMPTS, read_attempts
from rig.session.superblock import SIZE, parse
from tests.helpers.small_session import write_small_session

GIB = 1 << 30


@pytest.fixture(scope="module")
def good(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    """The bytes of a real small session file (``tests/helpers/small_session.py``)."""
    return write_small_session(tmp_path_factory.mktemp("good") / "session.h5", "damaged")


def _truncated(at: float) -> Callable[[bytes, Path], None]:
    """The first ``at`` bytes (a fraction of the file if < 1, all but ``-at`` if negative)."""
    def make(good: bytes, path: Path) -> None:
        n = int(at * len(good)) if 0 < at < 1 else int(at) % len(good)
        path.write_bytes(good[:n])

    return make


def _random_superblock(good: bytes, path: Path) -> None:
    path.write_bytes(good[:8] + random.Random(42).randbytes(SIZE - 8) + good[SIZE:])


def _flipped(where: str) -> Callable[[bytes, Path], None]:
    """One bit flipped inside the root group's object header, or inside the next object header (``/runs``)."""
    def make(good: bytes, path: Path) -> None:
        root = parse(good[:SIZE]).root
        at = root + 12 if where == "root" else good.index(b"OHDR", root + 4) + 12
        data = bytearray(good)
        data[at] ^= 0x04
        path.write_bytes(bytes(data))

    return make


def _zeros_after_first_page(good: bytes, path: Path) -> None:
    path.write_bytes(good[:4096] + bytes(len(good) - 4096))


def _sparse_zeros(good: bytes, path: Path) -> None:
    with open(path, "wb") as f:
        f.truncate(4 * GIB)


def _sparse_after_first_page(good: bytes, path: Path) -> None:
    with open(path, "wb") as f:
        f.write(good[:4096])
        f.truncate(4 * GIB)


DAMAGES = {
    "truncated-802": _truncated(802),
    "truncated-4096": _truncated(4096),
    "truncated-20000": _truncated(20000),
    "truncated-half": _truncated(0.5),
    "truncated-100-short": _truncated(-100),
    "random-superblock": _random_superblock,
    "flip-root-header": _flipped("root"),
    "flip-runs-header": _flipped("runs"),
    "zeros-after-first-page": _zeros_after_first_page,
    "sparse-4GiB-zeros": _sparse_zeros,
    "sparse-4GiB-first-page": _sparse_after_first_page,
}
TOOLS = {
    "sessions show": ["sessions", "show"],
    "sessions recover": ["sessions", "recover"],
    "analyze": ["analyze", "--no-write"],
    "report": ["report"],
    "run --resume": ["run", "--yes", "--resume"],
}


def _first_page(path: Path) -> bytes:
    """The first 4096 bytes of ``path`` (not the whole file: a sparse one is 4 GiB)."""
    with open(path, "rb") as f:
        return f.read(4096)


@pytest.fixture
def damaged(request: pytest.FixtureRequest, good: bytes, tmp_path: Path) -> Path:
    path = tmp_path / "session.h5"
    DAMAGES[request.param](good, path)
    return path


@pytest.mark.parametrize("damaged", list(DAMAGES), indirect=True)
def test_a_damaged_file_is_refused_by_the_readers(damaged: Path) -> None:
    with pytest.raises(DamagedFileError) as caught:
        read_session(damaged)
    message = str(caught.value)
    assert message.startswith(f"{damaged}: ") and "rig sessions recover cannot repair it" in message
    assert "\n" not in message


@pytest.mark.parametrize("tool", list(TOOLS))
@pytest.mark.parametrize("damaged", list(DAMAGES), indirect=True)
def test_every_tool_says_damaged_in_one_line(damaged: Path, tool: str, tmp_path: Path) -> None:
    args = [*TOOLS[tool], str(damaged)]
    if tool == "report":
        args += ["-o", str(tmp_path / "report.html")]
    before = damaged.stat().st_size, _first_page(damaged)
    result = CliRunner().invoke(app, args)
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 2, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    assert "Traceback" not in result.output
    assert lines[-1].startswith(f"damaged: {damaged}: ") and "rig sessions recover cannot repair it" in lines[-1]
    assert (damaged.stat().st_size, _first_page(damaged)) == before  # nothing written to it
    assert not (tmp_path / "report.html").exists()


def test_the_good_file_still_reads(good: bytes, tmp_path: Path) -> None:
    path = tmp_path / "session.h5"
    path.write_bytes(good)
    session = read_session(path)
    assert [run["status"] for run in session["runs"]] == ["completed", "completed"]
    assert session["runs"][1]["accel"]["plate"].shape == (3000, 4)
    result = CliRunner().invoke(app, ["sessions", "show", str(path)])
    assert result.exit_code == 0 and "completed" in result.output


def test_a_crashed_file_may_lack_its_unwritten_tail_but_a_closed_one_may_not(good: bytes, tmp_path: Path) -> None:
    """A killed writer leaves its flags set and may not have written all it allocated: not damaged (recover extends
    it). The same shortfall in a file no writer had open is a truncation."""
    sb = parse(good[:SIZE])
    path = tmp_path / "crashed.h5"
    path.write_bytes(sb.patched(flags=0x05) + good[SIZE:-4096])
    assert check_session(path).flags == 0x05
    path.write_bytes(good[:-4096])
    with pytest.raises(DamagedFileError, match=f"truncated: the file has {len(good) - 4096} bytes, its HDF5 "
                                               f"superblock says {sb.eoa}"):
        check_session(path)


def test_hdf5_retries_of_a_failing_block_are_bounded(good: bytes, tmp_path: Path) -> None:
    """HDF5 retries a metadata block whose checksum fails, sleeping 2^k ns before try k: a SWMR reader's default of
    100 tries never ends. Every reader's file-access list bounds them."""
    path = tmp_path / "session.h5"
    path.write_bytes(good)
    assert READ_ATTEMPTS <= 24  # at most 2^24 ns ≈ 17 ms of sleeps in all for one block
    with open_session(path) as h5:
        assert read_attempts(h5.id.get_access_plist()) == READ_ATTEMPTS
    with _open_any(path) as h5:
        assert read_attempts(h5.id.get_access_plist()) == READ_ATTEMPTS


@pytest.mark.parametrize("damaged", ["random-superblock", "truncated-802", "flip-runs-header"], indirect=True)
def test_a_damaged_file_that_no_writer_holds_is_not_retried(damaged: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The retries of a reader are for a file caught mid-update by its live writer; a file no one writes is
    answered at once (no sleep of the retry loop)."""
    sleeps: list[float] = []
    monkeypatch.setattr(reader.time, "sleep", sleeps.append)
    with pytest.raises(DamagedFileError):
        read_session(damaged)
    assert sleeps == []
