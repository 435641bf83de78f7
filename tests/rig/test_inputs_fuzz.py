"""Issue 25, inputs: mutated records, sequence files and rig configurations are refused with ``FILE:LINE: key:``.

The fuzz corpus (tests/data/fuzz, `expected.json` says what each file must be refused with) holds the cases
that once gave a traceback, a hang or an absurd value; FIFOs, symlinks to /dev/zero and /dev/urandom and
oversized files are made here. Property tests (hypothesis) per TOML schema: a sequence file with one number
replaced by any TOML value is either refused with its key and line or loads with every number inside its
documented range, and byte-mutated sequence files raise nothing but `SequenceError`. The record readers'
own property test is test_reader_fuzz.py.
"""

from __future__ import annotations

import json
import math
import os
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import tomli_w
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.input_file import MIB
from analysis.table.model import TableModel, TableModelError
from analysis.table.toml_check import MAX_TOML_BYTES
from rig.records import RecordError, read_record_file
from rig.records.source import MAX_FILE_BYTES
from rig.sequence import OperatorSteps, SequenceError, load_sequence
from rig.sequence.reader import MAX_REPETITIONS, RANGES

CORPUS = Path(__file__).parents[1] / "data" / "fuzz"
EXPECTED: dict[str, dict[str, Any]] = json.loads((CORPUS / "expected.json").read_text(encoding="utf-8"))
AT2 = Path(__file__).parents[1] / "data" / "records" / "RSN6_IMPVALL.I_I-ELC180.AT2"

READERS: dict[str, Callable[[Path], object]] = {
    "sequence": load_sequence,
    "rig": TableModel.from_toml,
    "records": read_record_file,
}
ERRORS = (SequenceError, TableModelError, RecordError)


# ---------------------------------------------------------------------------------------------------------
# The corpus: each file refused at its line and key, with the range or the reason
# ---------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_every_corpus_file_is_refused_at_its_line_and_key(name: str) -> None:
    case = EXPECTED[name]
    path = CORPUS / name
    with pytest.raises(ERRORS) as info:
        READERS[name.split("/")[0]](path)
    message = str(info.value)
    where = f"{path}:{case['line']}" if case["line"] else f"{path}"
    assert message.startswith(f"{where}: {case['key']}: " if case["key"] else f"{where}: "), message
    assert case["message"] in message, message
    assert len(message) < 600, message  # a 10 kB value or a 5,000-deep array is never echoed whole


# ---------------------------------------------------------------------------------------------------------
# FIFOs, devices behind symlinks, oversized files: refused before a byte is read
# ---------------------------------------------------------------------------------------------------------

SUFFIXES = {"sequence": ".toml", "rig": ".toml", "records": ".AT2", "h5 record": ".h5", "csv record": ".csv"}


def _reader(kind: str) -> Callable[[Path], object]:
    return READERS.get(kind, read_record_file)


@pytest.fixture
def fifo(tmp_path: Path) -> Iterator[Callable[[str], Path]]:
    """Make a FIFO whose writer (a thread) offers a valid record and ends: a reader that opens it would get
    the record and no hang; one that refuses it leaves the writer waiting, released at the end."""
    made: list[tuple[Path, threading.Thread]] = []

    def make(suffix: str) -> Path:
        path = tmp_path / f"fifo{len(made)}{suffix}"
        os.mkfifo(path)

        def feed() -> None:
            try:
                with path.open("wb") as writer:
                    writer.write(AT2.read_bytes())
            except BrokenPipeError:
                pass

        thread = threading.Thread(target=feed, daemon=True)
        thread.start()
        made.append((path, thread))
        return path

    yield make
    for path, thread in made:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # lets a waiting writer's open return
        thread.join()
        os.close(fd)


@pytest.mark.parametrize("kind", list(SUFFIXES))
def test_a_fifo_is_refused_unread(fifo: Callable[[str], Path], kind: str) -> None:
    path = fifo(SUFFIXES[kind])
    with pytest.raises(ERRORS) as info:
        _reader(kind)(path)
    assert str(info.value).startswith(f"{path}: ")
    assert "is a FIFO (named pipe); expected a" in str(info.value)


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom"])
@pytest.mark.parametrize("kind", list(SUFFIXES))
def test_a_symlink_to_a_device_is_refused_unread(tmp_path: Path, kind: str, device: str) -> None:
    path = tmp_path / f"link{SUFFIXES[kind]}"
    path.symlink_to(device)
    with pytest.raises(ERRORS) as info:
        _reader(kind)(path)
    assert str(info.value).startswith(f"{path}: is a character device; expected a")


def test_a_rig_config_naming_dev_zero_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "seq.toml"
    path.write_text((CORPUS / "sequence" / "config_dev_zero.toml").read_text())
    with pytest.raises(SequenceError) as info:
        load_sequence(path)
    assert info.value.key == "rig.config"
    assert info.value.problem == ("the rig configuration is refused: /dev/zero: is a character device; expected a "
                                  "rig configuration file (a regular file)")


@pytest.mark.parametrize(("kind", "limit"), [("sequence", MAX_TOML_BYTES), ("rig", MAX_TOML_BYTES),
                                             ("records", MAX_FILE_BYTES), ("h5 record", MAX_FILE_BYTES)])
def test_a_file_over_its_bound_is_refused_by_its_size(tmp_path: Path, kind: str, limit: int) -> None:
    path = tmp_path / f"big{SUFFIXES[kind]}"
    with path.open("wb") as f:
        f.truncate(limit + 1)  # sparse: nothing is written
    with pytest.raises(ERRORS) as info:
        _reader(kind)(path)
    assert str(info.value).startswith(f"{path}: is {limit + 1:,} bytes; expected a")
    assert f"of at most {limit:,} bytes" in str(info.value)


def test_the_bounds_are_the_stated_ones() -> None:
    assert (MAX_TOML_BYTES, MAX_FILE_BYTES) == (1 * MIB, 64 * MIB)


# ---------------------------------------------------------------------------------------------------------
# The prompt: a restricted formatter, never str.format on the user's text
# ---------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("template", [
    "Place the bodies ({angle_deg:g}°)", "{angle_deg:>6.1f} deg", "{angle_deg:08.3f}", "{bodies} for {sequence}",
    "{{literal braces}} at {angle_deg}", "{sequence:^20}|", "no placeholder at all",
])
def test_allowed_prompts_read_as_python_formats_them(template: str) -> None:
    values = {"angle_deg": 4.5, "bodies": "", "sequence": "quick"}
    assert OperatorSteps(place_bodies=template).place_prompt(4.5, (), "quick") == template.format(**values)


@pytest.mark.parametrize("template", [
    "{bodies.__class__.__init__.__globals__}", "{bodies[0]}", "{0}", "{}", "{bodies!r}", "{angle_deg:>1999999999}",
    "{angle_deg:.500f}", "{angle_deg:{sequence}}", "{unknown}", "{angle_deg", "x" * 501,
])
def test_a_prompt_built_in_code_is_refused_too(template: str) -> None:
    """`OperatorSteps` made without the reader (``Sequence.from_dict`` of a stored session, a test) is no
    way around the restriction."""
    with pytest.raises(ValueError, match=r"."):
        OperatorSteps(place_bodies=template).place_prompt(4.5)


# ---------------------------------------------------------------------------------------------------------
# Property tests of the sequence schema
# ---------------------------------------------------------------------------------------------------------

BASE: dict[str, Any] = {
    "name": "prop",
    "repetitions": 1,
    "angles_deg": [0, 4],
    "records": [{"record": "fema-farfield:KOBE/NIS000", "scale": 0.5, "window_s": [1.0, 5.0], "corner_hz": 1.0,
                 "dt_s": 0.01}],
    "plate": {"size_m": [3.0, 3.0]},
    "drive": {"settle_s": 1.0, "corner_hz": 1.0},
    "operator": {"place_bodies": "at {angle_deg:g}°"},
    "bodies": [{"b": 0.05, "h": 0.2, "depth": 0.1, "mass": 0.5, "x": 0.0, "y": 0.0, "friction": 0.8,
                "restitution": 0.9}],
}
#: Every number of the base and the range key it must respect (None: checked otherwise, e.g. x on the plate).
NUMBERS: dict[tuple[Any, ...], str | None] = {
    ("repetitions",): None, ("angles_deg", 1): None, ("records", 0, "scale"): "scale",
    ("records", 0, "window_s", 1): None, ("records", 0, "corner_hz"): "corner_hz", ("records", 0, "dt_s"): "dt_s",
    ("plate", "size_m", 0): "size_m", ("drive", "settle_s"): "settle_s", ("drive", "corner_hz"): "corner_hz",
    ("bodies", 0, "b"): "b", ("bodies", 0, "h"): "h", ("bodies", 0, "depth"): "depth", ("bodies", 0, "mass"): "mass",
    ("bodies", 0, "x"): None, ("bodies", 0, "friction"): "friction", ("bodies", 0, "restitution"): None,
}
VALUES = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-(2**63), 2**63 - 1), st.booleans(),
    st.text(max_size=8), st.lists(st.floats(allow_nan=False), max_size=3),
    st.sampled_from([1e-300, 1e300, 1e308, -0.0, 5e-324, 9.2e18, 1e9, 1e6, 1e-9]),
)


def _set(data: dict[str, Any], path: tuple[Any, ...], value: Any) -> None:
    for part in path[:-1]:
        data = data[part]
    data[path[-1]] = value


def _get(data: Any, path: tuple[Any, ...]) -> Any:
    for part in path:
        data = data[part]
    return data


def _check_loaded(path: Path, key_path: tuple[Any, ...]) -> None:
    """Load the sequence; a refusal must name the file and a key, a success hold every number in its range."""
    try:
        seq = load_sequence(path)
    except SequenceError as exc:
        assert str(exc).startswith(f"{path}:"), str(exc)
        assert exc.line is not None and exc.key, str(exc)
        return
    loaded = seq.to_dict()
    assert 1 <= seq.repetitions <= MAX_REPETITIONS
    assert all(0 <= angle <= 10 for angle in seq.angles_deg)
    for where, key in NUMBERS.items():
        if key is None:
            continue
        stored = {("records", 0, "dt_s"): seq.records[0].dt, ("records", 0, "corner_hz"): seq.records[0].corner,
                  ("records", 0, "scale"): seq.records[0].scale, ("drive", "corner_hz"): seq.drive.corner,
                  ("drive", "settle_s"): seq.drive.settle}.get(where)
        value = stored if stored is not None else _get(loaded, where)
        if value == "table":  # the scale policy, not a number
            continue
        low, high, _ = RANGES[key]
        assert math.isfinite(value) and low <= value <= high, (where, value)


@settings(max_examples=120, deadline=None, derandomize=True, database=None)
@given(where=st.sampled_from(sorted(NUMBERS, key=str)), value=VALUES)
def test_any_value_in_place_of_a_number_is_refused_or_in_range(tmp_path_factory: pytest.TempPathFactory,
                                                              where: tuple[Any, ...], value: Any) -> None:
    data = json.loads(json.dumps(BASE))
    _set(data, where, value)
    path = tmp_path_factory.mktemp("prop") / "seq.toml"
    path.write_text(tomli_w.dumps(data))
    _check_loaded(path, where)


def mutate(data: bytes, edits: list[tuple[float, bytes, bool]]) -> bytes:
    """Each edit replaces the line at a fraction of the file with a token, or inserts the token at that fraction."""
    for where, token, replace_line in edits:
        if replace_line:
            lines = data.splitlines(keepends=True) or [b""]
            lines[int(where * len(lines))] = token + b"\n"
            data = b"".join(lines)
        else:
            at = int(where * len(data))
            data = data[:at] + token + data[at:]
    return data


def fuzz_sequence_bytes(tmp_path: Path, examples: int) -> None:
    """Byte-mutated sequence files: a sequence or a `SequenceError` naming the file, nothing else."""
    original = tomli_w.dumps(BASE).encode()
    path = tmp_path / "mutated.toml"

    @settings(max_examples=examples, deadline=None, derandomize=True, database=None)
    @given(edits=st.lists(st.tuples(st.floats(0.0, 1.0, exclude_max=True),
                                    st.one_of(st.sampled_from(TOML_TOKENS), st.binary(max_size=6)), st.booleans()),
                          min_size=1, max_size=3))
    def run(edits: list[tuple[float, bytes, bool]]) -> None:
        path.write_bytes(mutate(original, edits))
        try:
            load_sequence(path)
        except SequenceError as exc:
            assert str(exc).startswith(f"{path}"), str(exc)

    run()


TOML_TOKENS = [
    b"[", b"]", b"{", b"}", b"=", b"\"", b"'''", b"[[bodies]]", b"[rig]", b"config = \"/dev/zero\"", b"1e308",
    b"-1e308", b"nan", b"inf", b"1e-300", b"0", b"-1", b"1000000000", b"\"{bodies.__class__}\"",
    b"settle_s = 1e6", b"corner_hz = 1e-9", b"table_url = \"http://example.com\"", b"[" * 200, b"\x00", b"\xff",
]


def test_byte_mutated_sequence_files_raise_only_sequence_errors(tmp_path: Path) -> None:
    fuzz_sequence_bytes(tmp_path, examples=150)


@pytest.mark.slow
def test_byte_mutated_sequence_files_raise_only_sequence_errors_deep(tmp_path: Path) -> None:
    fuzz_sequence_bytes(tmp_path, examples=3000)
