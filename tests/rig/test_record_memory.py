"""Long plain-text records (issue 42, item 3): parsed into arrays without a Python object per sample (peak memory per
sample measured with tracemalloc, numpy's arrays included), and a record with more samples than the limit refused
from its count of data lines, before a number is parsed, naming the file and the limit. The time it takes is
``benchmarks/record_memory.py``'s to say, not a test's."""

from __future__ import annotations

import tracemalloc
import warnings
from pathlib import Path

import numpy as np
import pytest

from rig.records import RecordError, RecordWarning
from rig.records import text as text_reader
from rig.records.text import read_text

GOAL_BYTES_PER_SAMPLE = 32


def _one_sample_a_line(path: Path, n: int) -> np.ndarray:
    values = np.round(np.random.default_rng(7).normal(0.0, 0.02, n), 3)
    path.write_text("# dt = 0.0005 s\n# units = g\n" + "\n".join(f"{v:g}" for v in values) + "\n")
    return values


def test_peak_memory_per_sample_of_a_long_record(tmp_path: Path) -> None:
    n = 200_000
    path = tmp_path / "long.txt"
    values = _one_sample_a_line(path, n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RecordWarning)  # the file name says no component
        tracemalloc.start()
        try:
            motion = read_text(path)
            _, peak = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
    assert np.array_equal(motion.acc_h, values) and motion.npts == n and motion.dt == 0.0005
    assert peak / n <= GOAL_BYTES_PER_SAMPLE, f"{peak / n:.1f} bytes per sample"


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
