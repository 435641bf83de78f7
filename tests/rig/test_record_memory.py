"""Long records (issue 42, item 3), plain text, PEER ``.AT2`` and CSV: parsed into arrays without a Python object per
sample (peak memory per sample measured with tracemalloc, numpy's arrays included), and a record with more samples
than the limit refused from its count of data lines or values, before a number is parsed, naming the file and the
limit. The time it takes is ``benchmarks/record_memory.py``'s to say, not a test's."""

from __future__ import annotations

import tracemalloc
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from rig.records import GroundMotion, RecordError, RecordWarning
from rig.records import cosmos as cosmos_reader
from rig.records import csvfile as csv_reader
from rig.records import peer as peer_reader
from rig.records import text as text_reader
from rig.records.cosmos import read_cosmos
from rig.records.csvfile import read_csv
from rig.records.peer import read_at2
from rig.records.source import TextSource
from rig.records.text import read_text

GOAL_BYTES_PER_SAMPLE = 32


def _one_sample_a_line(path: Path, n: int) -> np.ndarray:
    values = np.round(np.random.default_rng(7).normal(0.0, 0.02, n), 3)
    path.write_text("# dt = 0.0005 s\n# units = g\n" + "\n".join(f"{v:g}" for v in values) + "\n")
    return values


def test_a_record_too_long_is_refused_before_it_is_parsed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(text_reader, "MAX_SAMPLES", 1000)

    def parse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the samples were parsed")

    monkeypatch.setattr(text_reader.np, "loadtxt", parse)
    path = tmp_path / "long-HNE.txt"
    _one_sample_a_line(path, 1001)
    with pytest.raises(RecordError, match=rf"^{path}: the record has 1,001 samples \(data lines\); expected at most "
                                          r"1,000 \(refused before parsing them\)$"):
        read_text(path)
    _one_sample_a_line(path, 1000)
    monkeypatch.undo()
    assert read_text(path).npts == 1000


def _at2(path: Path, n: int, eol: str = "\n") -> np.ndarray:
    """A PEER NGA-West2 ``.AT2`` file of ``n`` samples in g, five of 15 characters a line (16 bytes a sample)."""
    values = np.random.default_rng(7).normal(0.0, 0.02, n)
    rows = [" ".join(f"{v:15.7E}" for v in values[i:i + 5]) for i in range(0, n, 5)]
    header = ["PEER NGA STRONG MOTION DATABASE RECORD", "Test, 1/1/2000, Station, H1",
              "ACCELERATION TIME SERIES IN UNITS OF G", f"NPTS= {n}, DT= .0050 SEC"]
    path.write_bytes((eol.join(header + rows) + eol).encode())
    return np.array([float(f"{v:15.7E}") for v in values])


def test_an_at2_record_too_long_is_refused_before_it_is_parsed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(peer_reader, "MAX_SAMPLES", 1000)

    def parse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the samples were parsed")

    monkeypatch.setattr(peer_reader.np, "fromstring", parse)
    monkeypatch.setattr(TextSource, "acceleration", parse)
    path = tmp_path / "long.AT2"
    _at2(path, 1001)
    with pytest.raises(RecordError, match=rf"^{path}: the record has 1,001 samples \(values after the header\); "
                                          r"expected at most 1,000 \(refused before parsing them\)$"):
        read_at2(path)
    _at2(path, 1000)
    monkeypatch.undo()
    assert read_at2(path).npts == 1000


def _csv(path: Path, n: int, time_column: bool) -> np.ndarray:
    """A CSV record of ``n`` samples in g: ``time_s,acc_g`` rows, or one ``acc_g`` column and a ``# dt`` line."""
    values = np.round(np.random.default_rng(7).normal(0.0, 0.02, n), 4)
    if time_column:
        path.write_text("time_s,acc_g\n" + "".join(f"{i * 0.005:.3f},{v:g}\n" for i, v in enumerate(values)))
    else:
        path.write_text("# dt = 0.005 s\nacc_g\n" + "".join(f"{v:g}\n" for v in values))
    return values


def test_a_csv_record_too_long_is_refused_before_it_is_parsed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(csv_reader, "MAX_SAMPLES", 1000)

    def parse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the samples were parsed")

    monkeypatch.setattr(csv_reader.np, "fromstring", parse)
    monkeypatch.setattr(TextSource, "number", parse)
    path = tmp_path / "long-HNE.csv"
    _csv(path, 1001, time_column=True)
    with pytest.raises(RecordError, match=rf"^{path}: the record has 1,001 samples \(data rows\); "
                                          r"expected at most 1,000 \(refused before parsing them\)$"):
        read_csv(path)
    _csv(path, 1000, time_column=True)
    monkeypatch.undo()
    assert read_csv(path).npts == 1000


def test_a_cosmos_channel_too_long_is_refused_before_it_is_parsed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    sine = Path(__file__).parents[1] / "data" / "records" / "cosmos_sine.V2"  # one channel of 22 values, line 49
    monkeypatch.setattr(cosmos_reader, "MAX_SAMPLES", 21)

    def parse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the samples were parsed")

    monkeypatch.setattr(TextSource, "acceleration", parse)
    with pytest.raises(RecordError, match=rf"^{sine}:49: the data header announces 22 values; expected at most 21 "
                                          r"\(refused before parsing them\)$"):
        read_cosmos(sine)
    monkeypatch.undo()
    monkeypatch.setattr(cosmos_reader, "MAX_SAMPLES", 22)
    assert read_cosmos(sine).npts == 22


def _cosmos(path: Path, n: int) -> np.ndarray:
    """cosmos_sine.V2 with ``n`` samples [cm/s²] in Format=(5E15.6) instead of its 22."""
    lines = (Path(__file__).parents[1] / "data" / "records" / "cosmos_sine.V2").read_text().splitlines()
    values = np.random.default_rng(7).normal(0.0, 20.0, n)
    rows = ["".join(f"{v:15.6e}" for v in values[i:i + 5]) for i in range(0, n, 5)]
    assert lines[48].startswith("      22 acceleration pts")
    path.write_text("\n".join([*lines[:48], lines[48].replace("      22", f"{n:8d}"), *rows, lines[-1]]) + "\n")
    return np.array([float(f"{v:15.6e}") for v in values]) * (0.01 / 9.81)


@dataclass(frozen=True)
class LongRecord:
    """A long record in one format: its file name, how many samples, how it is written (returning the values the
    reader must give, in g) and read, the line count the reader reports (None: not reported), its ``dt`` [s] (None:
    the file's own) and the goal [bytes a sample] given the file and its samples."""

    file_name: str
    samples: int
    write: Callable[[Path, int], np.ndarray]
    read: Callable[[Path], GroundMotion]
    lines: Callable[[int], int] | None = None
    dt: float | None = None
    goal: Callable[[Path, int], float] = lambda path, n: GOAL_BYTES_PER_SAMPLE


def _csv_time_acc_goal(path: Path, n: int) -> float:
    """The file's bytes are held while its rows are parsed into one float64 array per column: with a time column
    (16 bytes a row here) that alone is 32 bytes a sample; the bound says nothing else is kept per sample."""
    return path.stat().st_size / n + 8 * 2 + 1


LONG_RECORDS = {
    "text": LongRecord("long.txt", 200_000, _one_sample_a_line, read_text, dt=0.0005),
    "at2": LongRecord("long.AT2", 1_000_000, _at2, read_at2, lines=lambda n: 4 + n // 5, dt=0.005),
    "at2-crlf": LongRecord("long.AT2", 1_000_000, lambda path, n: _at2(path, n, "\r\n"), read_at2,
                           lines=lambda n: 4 + n // 5, dt=0.005),
    "csv-acc": LongRecord("long-HNE.csv", 1_000_000, lambda path, n: _csv(path, n, time_column=False), read_csv,
                          dt=0.005),
    "csv-time-acc": LongRecord("long-HNE.csv", 1_000_000, lambda path, n: _csv(path, n, time_column=True), read_csv,
                               dt=0.005, goal=_csv_time_acc_goal),
    # its values are still parsed one field at a time: 1 M takes too long for the fast tier
    "cosmos": LongRecord("long.V2", 100_000, _cosmos, read_cosmos, lines=lambda n: 48 + 1 + n // 5 + 1),
}


@pytest.mark.parametrize("case", LONG_RECORDS.values(), ids=LONG_RECORDS.keys())
def test_peak_memory_per_sample_of_a_long_record(tmp_path: Path, case: LongRecord) -> None:
    n = case.samples
    path = tmp_path / case.file_name
    values = case.write(path, n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RecordWarning)  # a file name that says no component
        tracemalloc.start()
        try:
            motion = case.read(path)
            _, peak = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
    assert np.array_equal(motion.acc_h, values) and motion.npts == n
    if case.dt is not None:
        assert motion.dt == case.dt
    if case.lines is not None:
        assert motion.provenance["lines"] == case.lines(n)
    assert peak / n <= case.goal(path, n), f"{peak / n:.1f} bytes per sample"
