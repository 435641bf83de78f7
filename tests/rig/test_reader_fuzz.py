"""Fuzz the record readers: real-layout files, mutated; only `RecordError` may escape.

Each case takes a file in one of the real layouts (tests/data/records, an own .h5 record written here, and
variants with CSMIP end lines, CR CR LF line ends and a vertical PEER component named on line 2),
applies a few mutations (delete, duplicate or replace a line, flip a bit, insert a token, truncate) and
reads the result. Either the reader raises `RecordError` naming the file, or the mutated file was still
valid and gives a valid `GroundMotion`: dt within the readers' range, at most `MAX_DURATION_S` long, every
channel finite, within `MAX_ABS_G` and with the same length as ``acc_h``, the provenance's npts and dt
equal to the motion's, and JSON-serialisable provenance.

The fast test runs a modest, derandomised number of cases per format; ``-m slow`` runs a deeper one.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rig.records import GroundMotion, RecordError, read_components, read_record_file, write_record
from rig.records.source import DT_MAX_S, DT_MIN_S, MAX_ABS_G, MAX_DURATION_S

DATA = Path(__file__).parents[1] / "data" / "records"
PAIR = ("RSN6_IMPVALL.I_I-ELC180.AT2", "RSN6_IMPVALL.I_I-ELC270.AT2", "RSN6_IMPVALL.I_I-ELC-UP.AT2")

#: Format → (source file, keyword arguments of the read); "h5" is written by `_h5_source`.
FORMATS: dict[str, tuple[str, dict[str, str]]] = {
    "at2-west2": ("RSN6_IMPVALL.I_I-ELC180.AT2", {}),
    "at2-nga": ("MUL009.AT2", {}),
    "text-1col": ("ELC180_gal.txt", {}),
    "text-2col": ("two_column.dat", {"units": "g"}),
    "csv-units-in-header": ("ELC180_cm.csv", {}),
    "csv-3-components": ("three_components.csv", {}),
    "h5": ("record.h5", {}),
    "pair-vertical": (PAIR[2], {}),
    "cosmos-1-channel": ("cosmos_sine.V2", {}),
    "cosmos-3-channels": ("cosmos_3chan.V2C", {}),
    "cosmos-touching-fields": ("cosmos_touching.v1", {}),
    "cosmos-csmip-end-cr-cr-lf": ("csmip_end_crcrlf.V2", {}),
    "at2-cr-cr-lf-vertical-on-line-2": ("RSN6_crcrlf_HNZ.AT2", {}),
}

TOKENS = [
    b"nan", b"-inf", b"1e999", b"-1D+400", b"0", b"-0.0", b"1D-3", b".5E-02", b"abc", b",", b"#", b"\t",
    b"# dt = 0", b"# dt = -0.01 s", b"# units = furlong", b"# units = g", b"# npts = 3", b"# dt = 0.02",
    b"NPTS=", b"NPTS=     12, DT=   .0000 SEC,", b"  12   0.0100   NPTS, DT", b"IN UNITS OF CM/S/S",
    b"\x00", b"\xff\xfe", b"\xc3\xa9", b"\r", b"\n", b"\r\n", b"1.5.2", b"0x10", b"9" * 400, b"1e308",
    b"time_s,acc_g", b"t [s],acc_h2 [g]", b'"0.1"', b"", b" ",
    b"End-of-data for Chan  1 acceleration", b"     401", b"     400", b"    -999", b"-999.000000", b"(04)", b"(02)",
    b"units=g(02)", b"Format=(8F10.5)", b"(1E15.6)", b" 100 Integer-header values follow on  10 lines",
    b"with 14 text lines", b"velocity", b"|", b"-123.456-234.567",
    b"/&  ----------  End of data for channel  1  ----------", b"\r\r\n", b"\r\r", b"     0", b"    2000",
    b"CORRECTED ACCELEROGRAM DATA", b"UNCORRECTED ACCELEROGRAM DATA", b", UP", b", HNZ", b", 090", b"-UP",
    b"DT= 1e-300 SEC", b"DT= 1e300 SEC", b"# dt = 1e-300", b"# dt = 1e300 s", b"1e300", b"1e-300", b" " * 1200,
    b"_x" * 600, b", BHZ00", b", HN1.10", b", HNA", b"HNZ_g", b"time_s,HN1_g,HN2_g,HNZ_g", b"  1000000000   1.0",
]

_offset = st.floats(min_value=0.0, max_value=1.0, allow_nan=False, exclude_max=True)
_token = st.one_of(st.sampled_from(TOKENS), st.binary(max_size=6))
MUTATION = st.one_of(
    st.tuples(st.just("delete line"), _offset),
    st.tuples(st.just("duplicate line"), _offset),
    st.tuples(st.just("replace line"), _offset, _token),
    st.tuples(st.just("flip bit"), _offset, st.integers(0, 7)),
    st.tuples(st.just("insert token"), _offset, _token),
    st.tuples(st.just("truncate"), _offset),
)
MUTATIONS = st.lists(MUTATION, min_size=1, max_size=3)


def mutate(data: bytes, mutations: list[tuple]) -> bytes:
    """Apply the mutations in order; offsets are fractions of the current length."""
    for kind, where, *arg in mutations:
        lines = data.splitlines(keepends=True) or [b""]
        i = int(where * len(lines))
        at = int(where * len(data))
        if kind == "delete line":
            del lines[i]
        elif kind == "duplicate line":
            lines.insert(i, lines[i])
        elif kind == "replace line":
            lines[i] = arg[0] + b"\n"
        if kind in ("delete line", "duplicate line", "replace line"):
            data = b"".join(lines)
        elif kind == "flip bit" and data:
            data = data[:at] + bytes([data[at] ^ (1 << arg[0])]) + data[at + 1 :]
        elif kind == "insert token":
            data = data[:at] + arg[0] + data[at:]
        elif kind == "truncate":
            data = data[:at]
    return data


def assert_valid(motion: GroundMotion) -> None:
    """What every motion a reader returns must satisfy: dt, length and accelerations in their physical ranges."""
    assert DT_MIN_S <= motion.dt <= DT_MAX_S and motion.duration <= MAX_DURATION_S
    assert motion.npts >= 1 and motion.units == "g"
    for channel in (motion.acc_h, motion.acc_h2, motion.acc_v):
        if channel is not None:
            assert channel.shape == (motion.npts,)
            assert np.all(np.isfinite(channel)) and np.all(np.abs(channel) <= MAX_ABS_G)
    provenance = motion.provenance
    json.dumps(provenance, allow_nan=False)
    if "npts" in provenance:
        assert provenance["npts"] == motion.npts
    if "dt" in provenance:
        assert provenance["dt"] == motion.dt


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A directory with the sources (tests/data/records) and an own .h5 record written from the CSV."""
    root = tmp_path_factory.mktemp("fuzz")
    for path in DATA.iterdir():
        shutil.copy(path, root / path.name)
    write_record(read_record_file(DATA / "three_components.csv"), root / "record.h5")
    csmip_end = (DATA / "cosmos_sine.V2").read_bytes().replace(
        b"End-of-data for Chan  1 acceleration", b"/&  ----------  End of data for channel  1  ----------")
    (root / "csmip_end_crcrlf.V2").write_bytes(csmip_end.replace(b"\n", b"\r\r\n"))
    vertical = (DATA / "RSN6_IMPVALL.I_I-ELC-UP.AT2").read_bytes().replace(b"Array #9, UP", b"Array #9, HNZ")
    (root / "RSN6_crcrlf_HNZ.AT2").write_bytes(vertical.replace(b"\n", b"\r\r\n"))
    return root


def _reader(workdir: Path, fmt: str, target: Path) -> Callable[[], GroundMotion]:
    """How a mutated ``target`` file of format ``fmt`` is read."""
    kwargs = FORMATS[fmt][1]
    if fmt == "pair-vertical":
        return lambda: read_components([workdir / PAIR[0], workdir / PAIR[1], target])
    return lambda: read_record_file(target, **kwargs)


def fuzz(workdir: Path, fmt: str, examples: int) -> None:
    """Run ``examples`` mutated files of one format through its reader."""
    name = FORMATS[fmt][0]
    original = (workdir / name).read_bytes()
    target = workdir / "mutated" / name
    target.parent.mkdir(exist_ok=True)
    read = _reader(workdir, fmt, target)

    @settings(max_examples=examples, deadline=None, derandomize=True, database=None)
    @given(mutations=MUTATIONS)
    def run(mutations: list[tuple]) -> None:
        target.write_bytes(mutate(original, mutations))
        try:
            motion = read()
        except RecordError as exc:
            assert str(target) in str(exc), str(exc)
            return
        assert_valid(motion)

    run()


def test_unmutated_sources_are_valid(workdir: Path) -> None:
    for fmt, (name, _) in FORMATS.items():
        assert_valid(_reader(workdir, fmt, workdir / name)())


@pytest.mark.parametrize("fmt", list(FORMATS))
def test_fuzz_readers(workdir: Path, fmt: str) -> None:
    fuzz(workdir, fmt, examples=150)


@pytest.mark.slow
@pytest.mark.parametrize("fmt", list(FORMATS))
def test_fuzz_readers_deep(workdir: Path, fmt: str) -> None:
    fuzz(workdir, fmt, examples=3000)
