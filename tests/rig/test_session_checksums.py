"""Checksums of a session's samples (issue 42, item 2): a CRC-32 per block the writer flushed, in each run's
``checksums`` table, verified where a file is read for analysis. A bit flipped in the samples of a real small
session is refused by ``rig analyze`` and ``rig report`` as ``damaged: FILE: run N dataset D rows a–b: checksum …``;
an untouched file passes; rows after the last checksummed block (a killed writer) are unverified, not damaged; a
run written before checksums reads as "not checksummed".
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from rig.cli import app
from rig.session import DamagedFileError, read_session
from rig.session import checksums as crc
from tests.helpers.small_session import write_small_session


@pytest.fixture(scope="module")
def good(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    """The bytes of a real small session file (``tests/helpers/small_session.py``)."""
    return write_small_session(tmp_path_factory.mktemp("good") / "session.h5", "checksums")


def _copy(good: bytes, tmp_path: Path) -> Path:
    path = tmp_path / "session.h5"
    path.write_bytes(good)
    return path


def _flip(path: Path, dataset: str, row: int) -> None:
    """Flip one bit in the stored bytes of ``row`` of ``dataset`` (a run's sample data, not HDF5 metadata)."""
    with h5py.File(path, "r") as h5:
        ds = h5[dataset]
        chunk = ds.id.get_chunk_info(0)
        offset = chunk.byte_offset + row * ds.dtype.itemsize * int(np.prod(ds.shape[1:])) + 3
    data = bytearray(path.read_bytes())
    data[offset] ^= 0x10
    path.write_bytes(bytes(data))


@pytest.mark.parametrize(("dataset", "row"), [("accel/plate", 1500), ("commanded", 40), ("tilt/1", 2999),
                                              ("detections", 0), ("bodies", 0)])
def test_a_bit_flipped_in_the_samples_is_refused_naming_the_dataset(good: bytes, tmp_path: Path, dataset: str,
                                                                    row: int) -> None:
    path = _copy(good, tmp_path)
    _flip(path, f"runs/0002/{dataset}", row)
    with pytest.raises(DamagedFileError) as caught:
        read_session(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: run 0002 dataset {dataset} rows ")
    assert ": checksum 0x" in message and "\n" not in message


@pytest.mark.parametrize("tool", ["analyze", "report"])
def test_analyze_and_report_refuse_a_bit_flipped_file_in_one_line(good: bytes, tmp_path: Path, tool: str) -> None:
    path = _copy(good, tmp_path)
    _flip(path, "runs/0001/accel/plate", 10)
    args = ["analyze", "--no-write", str(path)] if tool == "analyze" else \
        ["report", str(path), "-o", str(tmp_path / "report.html")]
    result = CliRunner().invoke(app, args)
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert lines[-1].startswith(f"damaged: {path}: run 0001 dataset accel/plate rows 0–"), lines[-1]
    assert "checksum 0x" in lines[-1]
    assert not (tmp_path / "report.html").exists()


def test_an_untouched_file_is_verified_and_analysed(good: bytes, tmp_path: Path) -> None:
    path = _copy(good, tmp_path)
    session = read_session(path)
    for run in session["runs"]:
        assert run["checksums"] == {"state": "verified", "unverified": {}}
    with h5py.File(path, "r") as h5:
        table = h5["runs/0001/checksums"][()]
    covered = {bytes(name).decode() for name in table["dataset"]}
    assert covered == {"commanded", "bodies", "accel/plate", "tilt/1", "detections", "events"}
    for tool in (["analyze", "--no-write", str(path)], ["report", str(path), "-o", str(tmp_path / "r.html")]):
        result = CliRunner().invoke(app, tool)
        assert result.exit_code == 0, result.output


def test_rows_after_the_last_checksummed_block_are_unverified_not_damaged(good: bytes, tmp_path: Path) -> None:
    """What a writer killed between a flush and the next leaves: its last block's rows without their checksum row."""
    path = _copy(good, tmp_path)
    with h5py.File(path, "r+") as h5:
        table = h5["runs/0002/checksums"]
        rows = table[()]
        keep = rows[[bytes(name) != b"accel/plate" for name in rows["dataset"]]]
        table.resize(len(keep), axis=0)
        table[:] = keep
        h5["runs/0002"].attrs["status"] = "interrupted"
    run = read_session(path)["runs"][1]
    assert run["checksums"] == {"state": "verified", "unverified": {"accel/plate": [0, 3000]}}
    assert run["accel"]["plate"].shape == (3000, 4)
    report = tmp_path / "report.html"
    result = CliRunner().invoke(app, ["report", str(path), "-o", str(report)])
    assert result.exit_code == 0, result.output
    assert "accel/plate rows 0–2999 unverified" in report.read_text()


def test_a_checksummed_block_missing_from_its_dataset_is_damage_unless_the_run_is_recorded() -> None:
    data = np.arange(40.0).reshape(10, 4)
    blocks = {"accel/plate": [(0, 6, crc.crc32(data[:6])), (6, 6, 0)]}
    with pytest.raises(DamagedFileError, match=r"run 0003 dataset accel/plate rows 6–11: missing: the dataset has "
                                               r"10 rows"):
        crc.verify(Path("s.h5"), "0003", blocks, {"accel/plate": data}, recording=False)
    live = crc.verify(Path("s.h5"), "0003", blocks, {"accel/plate": data}, recording=True)
    assert live.verified_rows == {"accel/plate": 6} and live.unverified == {"accel/plate": (6, 10)}
    with pytest.raises(DamagedFileError, match="block out of sequence"):
        crc.verify(Path("s.h5"), "0003", {"accel/plate": [(2, 4, 0)]}, {"accel/plate": data}, recording=False)


def test_a_run_written_before_checksums_reads_as_not_checksummed(good: bytes, tmp_path: Path) -> None:
    path = _copy(good, tmp_path)
    with h5py.File(path, "r+") as h5:
        for name in h5["runs"]:
            del h5["runs"][name]["checksums"]
    session = read_session(path)
    assert [run["checksums"]["state"] for run in session["runs"]] == ["not checksummed"] * 2
    result = CliRunner().invoke(app, ["analyze", "--no-write", str(path)])
    assert result.exit_code == 0, result.output
    assert "run 0001: samples not checksummed" in " ".join(result.output.split())
