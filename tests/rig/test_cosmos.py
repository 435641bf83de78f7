"""COSMOS strong-motion files (format v01.20, V1/V2): layout, channels, fixed-width fields and located errors.

The three files under tests/data/records are synthetic records written in the real layout (text header
with its line count on line 1, 100 integer values in (10I8), 100 real values, "|" comments, the data
header with count, quantity, unit code and Fortran format, the values, End-of-data):

* cosmos_sine.V2 — one corrected channel: a 10 Hz sine of amplitude 98.1 cm/s² (0.1 g) sampled every
  5 ms (real-header value 62 = 5.0 ms), 22 samples printed (5E15.6), each rounded to 1e-4 cm/s²;
* cosmos_3chan.V2C — three channels as a CESMD free-field file: chan 1 at 360°, chan 2 Up, chan 3 at 90°,
  each an acceleration, a velocity and a displacement block, dt = 10 ms, 20 samples in (8F10.5);
  acceleration [cm/s²] chan 1: 1.5 i - 10, chan 2: 0.25 i, chan 3: 5 - 2 i (i = 0 … 19);
* cosmos_touching.v1 — one uncorrected channel in (10F8.3) whose fields touch (``-234.567-345.678``),
  real header in (6F13.6), dt = 20 ms.

Variants (units, orientation, damage) are derived from them here; a few errors are checked word for word.
"""

from __future__ import annotations

import hashlib
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from rig.records import GroundMotion, RecordError, load_record, read_cosmos, read_record_file

DATA = Path(__file__).parents[1] / "data" / "records"
SINE = DATA / "cosmos_sine.V2"
THREE = DATA / "cosmos_3chan.V2C"
TOUCHING = DATA / "cosmos_touching.v1"
#: cm/s² → g with g = 9.81 m/s² (the lab's convention), as the readers convert.
CM_TO_G = 0.01 / 9.81
#: The sine's samples [cm/s²] as printed in cosmos_sine.V2.
SINE_CM = [round(98.1 * math.sin(math.pi * i / 10), 4) for i in range(22)]
#: The acceleration channels of cosmos_3chan.V2C [cm/s²].
CHAN1_CM = [1.5 * i - 10 for i in range(20)]
CHAN2_UP_CM = [0.25 * i for i in range(20)]
CHAN3_CM = [5 - 2.0 * i for i in range(20)]
#: The samples of cosmos_touching.v1 [cm/s²].
TOUCHING_CM = [123.456, -234.567, -345.678, 12.5, -100.25, -999.999, 0.0, 456.789, -567.891, -0.001, -678.912,
               -111.111, 222.222]


def error_of(read: object, *args: object, **kwargs: object) -> str:
    """The message of the `RecordError` that ``read(*args, **kwargs)`` raises."""
    with pytest.raises(RecordError) as info:
        read(*args, **kwargs)  # type: ignore[operator]
    return str(info.value)


def variant(tmp_path: Path, source: Path, name: str, *changes: tuple[str, str, int]) -> Path:
    """A copy of ``source`` named ``name`` with each (old, new, count) replaced; ``old`` must occur ``count`` times."""
    text = source.read_text()
    for old, new, count in changes:
        assert text.count(old) == count, (old, text.count(old))
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text)
    return path


def lines_of(source: Path, first: int, last: int) -> str:
    """Lines ``first``-``last`` (1-based, inclusive) of a file, with their line breaks."""
    return "".join(source.read_text().splitlines(keepends=True)[first - 1 : last])


# --------------------------------------------------------------------------------------------------
# Reading the layouts
# --------------------------------------------------------------------------------------------------


def test_single_channel_sine_in_g_with_dt_from_real_header_value_62() -> None:
    gm = read_cosmos(SINE)
    assert gm.name == "cosmos_sine"
    assert (gm.dt, gm.npts) == (0.005, 22)  # 5.0 ms
    assert gm.acc_h.tolist() == [v * CM_TO_G for v in SINE_CM]  # decimal text → the same doubles
    t = np.arange(22) * 0.005
    np.testing.assert_allclose(gm.acc_h, 0.1 * np.sin(2 * np.pi * 10 * t), rtol=0, atol=1e-7)
    assert gm.pga == pytest.approx(0.1, rel=1e-15)
    assert gm.acc_h2 is None and gm.acc_v is None
    p = gm.provenance
    assert (p["format"], p["lines"], p["npts"], p["dt"]) == ("COSMOS v01.20", 55, 22, 0.005)
    assert p["title"] == "Corrected acceleration    (Format v01.20 with 13 text lines) Src: synthetic"
    assert p["blocks"] == [{"line": 1, "quantity": "acceleration", "npts": 22, "kept": True}]
    assert p["channels"] == {
        "h": {
            "line": 1, "title": p["title"], "channel": 1, "orientation": "360 deg", "orientation_code": 360,
            "negated_to_up": False, "units_in_file": "cm/sec2", "unit_code": 4, "to_g": CM_TO_G,
            "format": "5E15.6", "npts": 22, "dt": 0.005,
        }
    }
    assert p["source_sha256"] == hashlib.sha256(SINE.read_bytes()).hexdigest()
    assert p["path"] == str(SINE.resolve())
    json.dumps(p, allow_nan=False)


def test_three_channels_make_one_bidirectional_record_with_its_vertical() -> None:
    gm = read_cosmos(THREE)
    assert (gm.dt, gm.npts) == (0.01, 20)
    assert gm.acc_h.tolist() == [v * CM_TO_G for v in CHAN1_CM]  # chan 1, 360 deg: first horizontal
    assert gm.acc_h2 is not None and gm.acc_h2.tolist() == [v * CM_TO_G for v in CHAN3_CM]  # chan 3, 90 deg
    assert gm.acc_v is not None and gm.acc_v.tolist() == [v * CM_TO_G for v in CHAN2_UP_CM]  # chan 2, Up
    p = gm.provenance
    channels = {role: (c["channel"], c["orientation"], c["line"]) for role, c in p["channels"].items()}
    assert channels == {"h": (1, "360 deg", 1), "h2": (3, "90 deg", 319), "v": (2, "Up", 160)}
    # each channel's velocity and displacement blocks were read, checked and skipped
    assert [(b["line"], b["quantity"], b["kept"]) for b in p["blocks"]] == [
        (1, "acceleration", True), (54, "velocity", False), (107, "displacement", False),
        (160, "acceleration", True), (213, "velocity", False), (266, "displacement", False),
        (319, "acceleration", True), (372, "velocity", False), (425, "displacement", False),
    ]
    assert p["sha256"] == hashlib.sha256(np.asarray(gm.acc_h, dtype="<f8").tobytes()).hexdigest()
    json.dumps(p, allow_nan=False)


def test_down_vertical_is_negated_to_up(tmp_path: Path) -> None:
    down = variant(tmp_path, THREE, "down.V2C", ("     400", "     401", 3))  # chan 2: its three blocks
    gm = read_cosmos(down)
    assert gm.acc_v is not None and gm.acc_v.tolist() == [-v * CM_TO_G for v in CHAN2_UP_CM]
    v = gm.provenance["channels"]["v"]
    assert (v["orientation"], v["orientation_code"], v["negated_to_up"]) == ("Down (negated to up)", 401, True)
    assert gm.acc_h.tolist() == read_cosmos(THREE).acc_h.tolist()


def test_touching_fixed_width_fields_are_split_by_width() -> None:
    assert "-234.567-345.678" in TOUCHING.read_text()
    gm = read_cosmos(TOUCHING)
    assert (gm.dt, gm.npts) == (0.02, 13)
    assert gm.acc_h.tolist() == [v * CM_TO_G for v in TOUCHING_CM]
    h = gm.provenance["channels"]["h"]
    assert (h["format"], h["orientation"]) == ("10F8.3", "90 deg")
    assert gm.provenance["title"].startswith("Uncorrected acceleration")


def test_unit_code_g_and_one_value_a_line(tmp_path: Path) -> None:
    # the same record in g, one value a line (1E15.6) as USGS files write it
    values = [0.1, -0.25, 0.0125]
    text = SINE.read_text()
    head = text[: text.index("      22 acceleration")]
    data = "".join(f"{v:15.6e}\n" for v in values)
    path = tmp_path / "g.v2c"
    path.write_text(
        head.replace("       2       1       4     120", "       2       1       2     120")
        + "       3 acceleration pts, approx    0 secs, units=g(02),Format=(1E15.6)\n"
        + data
        + "End-of-data for Chan  1 acceleration\n"
    )
    gm = read_cosmos(path, units="g", dt=0.005)
    assert gm.acc_h.tolist() == values
    assert (gm.provenance["channels"]["h"]["unit_code"], gm.provenance["channels"]["h"]["to_g"]) == (2, 1.0)


def test_given_dt_and_units_must_agree_with_the_file() -> None:
    assert read_cosmos(SINE, dt=0.005, units="gal").dt == 0.005
    assert error_of(read_cosmos, SINE, dt=0.01) == (
        f"{SINE}:38: the file gives dt = 0.005 s but dt = 0.01 s was given; expected the same dt"
    )
    assert error_of(read_cosmos, SINE, units="g") == (
        f"{SINE}:49: the file gives the unit cm/s/s but g was given; expected the same unit"
    )


# --------------------------------------------------------------------------------------------------
# Malformed files: word for word
# --------------------------------------------------------------------------------------------------


def test_error_truncated_file_word_for_word(tmp_path: Path) -> None:
    cut = tmp_path / "cut.V2"
    cut.write_text(lines_of(SINE, 1, 53))  # the last data line and End-of-data are gone
    assert error_of(read_cosmos, cut) == (
        f"{cut}:53: truncated file: it ends at line 53; expected values 21-22 of the 22 acceleration values "
        "announced on line 49 on line 54"
    )
    no_end = tmp_path / "no_end.V2"
    no_end.write_text(lines_of(SINE, 1, 54))
    assert error_of(read_cosmos, no_end) == (
        f"{no_end}:54: truncated file: it ends at line 54; expected 'End-of-data for Chan …' after the 22 "
        "acceleration values announced on line 49 on line 55"
    )


@pytest.mark.parametrize(
    ("old", "new", "line", "message"),
    [
        ("      22 acceleration", "      23 acceleration", 54,
         "2 field(s) of 15 characters on the line; expected 3 (the 23 acceleration values announced on line 49, "
         "Format=(5E15.6))"),
        ("      22 acceleration", "      20 acceleration", 54,
         "extra data or a missing end line: the 20 acceleration values announced on line 49 take 4 lines of "
         "Format=(5E15.6), but line 54 is '0.000000e+00   3.031460e+01'; expected 'End-of-data for Chan …'"),
        ("with 13 text lines", "with 12 text lines", 13,
         "expected the integer header line ' 100 Integer-header values follow on  10 lines, Format= (10I8)', "
         "got 'Values used when parameter or data value is unknown/unspecified:   ...'"),
        ("   2 Comment line(s)", "   3 Comment line(s)", 49,
         "expected comment 3 of the 3 announced on line 46, starting with '|', got '22 acceleration pts, approx"
         "    0 secs, units=cm/sec2(04),Format=(5E...'"),
        (" 100 Real-header values follow on  20 lines", " 100 Real-header values follow on  19 lines", 25,
         "100 real header values on 19 lines do not fit Format=(5F15.6), which puts 5 a line; expected 20 lines"),
    ],
)
def test_error_counts_disagreeing_with_the_lines_word_for_word(
    tmp_path: Path, old: str, new: str, line: int, message: str
) -> None:
    path = variant(tmp_path, SINE, "bad.V2", (old, new, 1))
    assert error_of(read_cosmos, path) == f"{path}:{line}: {message}"


@pytest.mark.parametrize(
    ("old", "new", "line", "message"),
    [
        ("   5.766170e+01   7.936460e+01   9.329860e+01\n   9.81", "   5.76x170e+01   7.936460e+01   9.329860e+01\n"
         "   9.81", 50,
         "field 3 (columns 31-45), '5.76x170e+01', is not a number; expected a decimal number such as -1.25E-02"),
        ("   0.000000e+00   3.031460e+01\n", "   0.000000e+00            nan\n", 54,
         "field 2 (columns 16-30) is 'nan'; expected a finite number"),
        ("   0.000000e+00   3.031460e+01\n", "   0.000000e+00          3E+01\n", 54,
         "field 2 (columns 16-30), '3E+01', has no decimal point; expected a number as Format=(5E15.6) writes it"),
        ("    -999.000000       5.000000", "    -999.000000    -999.000000", 38,
         "the sampling interval (real-header value 62) is unknown (-999); expected the interval in milliseconds, "
         "e.g. 10.0"),
        ("    -999.000000       5.000000", "    -999.000000       0.000000", 38,
         "the sampling interval (real-header value 62), 0 ms, is not a record's time step; expected 1e-05 s to 1 s, "
         "such as 0.01 s (given in ms, e.g. 10.0)"),
        ("units=cm/sec2(04)", "units=cm/sec2(14)", 49,
         "the data header gives unit code 14 but integer-header value 3 (line 15) is 4; expected the same unit "
         "code"),
        ("End-of-data for Chan  1 acceleration", "End of record", 55,
         "extra data or a missing end line: the 22 acceleration values announced on line 49 take 5 lines of "
         "Format=(5E15.6), but line 55 is 'End of record'; expected 'End-of-data for Chan …'"),
    ],
)
def test_error_malformed_fields_and_headers_word_for_word(
    tmp_path: Path, old: str, new: str, line: int, message: str
) -> None:
    path = variant(tmp_path, SINE, "bad.V2", (old, new, 1))
    assert error_of(read_cosmos, path) == f"{path}:{line}: {message}"


def test_error_unsupported_unit_code_word_for_word(tmp_path: Path) -> None:
    path = variant(
        tmp_path, SINE, "inches.V2",
        ("       2       1       4     120", "       2       1       7     120", 1),
        ("units=cm/sec2(04)", "units=in/sec2(07)", 1),
    )
    assert error_of(read_cosmos, path) == (
        f"{path}:49: unit code 07 (in/s/s) is not a supported acceleration unit; expected 02 (g), 04 (cm/s/s) "
        "or 10 (gal)"
    )


def test_error_no_acceleration_block_word_for_word(tmp_path: Path) -> None:
    velocity = tmp_path / "velocity.V2C"
    velocity.write_text(lines_of(THREE, 54, 106))  # chan 1's velocity block alone
    assert error_of(read_cosmos, velocity) == (
        f"{velocity}:1: no acceleration block (found velocity (line 1)); expected at least one acceleration "
        "block (a V1 or V2 acceleration file)"
    )


def test_two_horizontal_channels_are_one_bidirectional_record(tmp_path: Path) -> None:
    two = tmp_path / "two.V2C"
    two.write_text(lines_of(THREE, 1, 159) + lines_of(THREE, 319, 477))  # chan 1 (360 deg) and chan 3 (90 deg)
    motion, three = read_cosmos(two), read_cosmos(THREE)
    np.testing.assert_array_equal(motion.acc_h, three.acc_h)
    assert motion.acc_h2 is not None and three.acc_h2 is not None
    np.testing.assert_array_equal(motion.acc_h2, three.acc_h2)
    assert motion.acc_v is None and sorted(motion.provenance["channels"]) == ["h", "h2"]


def test_error_channel_combinations_word_for_word(tmp_path: Path) -> None:
    up = variant(tmp_path, THREE, "up.V2C", ("     360", "     400", 3))
    assert error_of(read_cosmos, up) == (
        f"{up}: 3 acceleration channels (chan 1 (line 1): Up; chan 2 (line 160): Up; chan 3 (line 319): "
        "90 deg); expected one channel, or two horizontal and at most one vertical (orientation = integer-header "
        "value 54)"
    )
    flat = variant(tmp_path, THREE, "flat.V2C", ("     400", "      90", 3))
    assert error_of(read_cosmos, flat) == (
        f"{flat}: 3 acceleration channels (chan 1 (line 1): 360 deg; chan 2 (line 160): 90 deg; chan 3 (line 319): "
        "90 deg); expected one channel, or two horizontal and at most one vertical (orientation = integer-header "
        "value 54)"
    )


def test_error_channels_with_different_dt_or_length_word_for_word(tmp_path: Path) -> None:
    lines = THREE.read_text().splitlines(keepends=True)
    slow = tmp_path / "slow.V2C"
    slow.write_text("".join([*lines[:355], lines[355].replace("10.000000", "20.000000"), *lines[356:]]))
    assert error_of(read_cosmos, slow) == (
        f"{slow}:356: chan 3 has dt = 0.02 s but chan 1 (line 38) has dt = 0.01 s; expected the channels of one "
        "record to share dt"
    )
    short = tmp_path / "short.V2C"
    header, last = lines[366].replace("      20 acceleration", "      19 acceleration"), lines[369][:30] + "\n"
    short.write_text("".join([*lines[:366], header, *lines[367:369], last, *lines[370:]]))
    assert error_of(read_cosmos, short) == (
        f"{short}:367: chan 3 has 19 samples but chan 1 (line 49) has 20; expected the same number of samples in "
        "every channel"
    )


def test_error_non_utf8_and_empty_files_word_for_word(tmp_path: Path) -> None:
    latin1 = tmp_path / "latin1.V2"
    latin1.write_bytes(SINE.read_bytes().replace(b"Synthetic Test", b"Synth\xe9tic Test"))
    assert error_of(read_cosmos, latin1) == (
        f"{latin1}:2: byte 0xe9 at column 16 is not UTF-8 text; expected a UTF-8 text file"
    )
    empty = tmp_path / "empty.v1"
    empty.write_text("\n\n")
    assert error_of(read_cosmos, empty) == (
        f"{empty}:1: the file is empty; expected a COSMOS strong-motion file: blocks of text, integer and real "
        "headers, comments and data"
    )
    other = tmp_path / "peer.V2"
    other.write_text((DATA / "MUL009.AT2").read_text())
    assert error_of(read_cosmos, other).startswith(
        f"{other}:1: expected the first line of a COSMOS block, e.g. 'Corrected acceleration    (Format v01.20 with "
        "13 text lines)', got "
    )


@pytest.mark.parametrize("newline", ["\r\n", "\r"])
def test_crlf_and_cr_line_ends(tmp_path: Path, newline: str) -> None:
    path = tmp_path / "dos.V2C"
    path.write_bytes(THREE.read_bytes().replace(b"\n", newline.encode()))
    gm = read_cosmos(path)
    assert gm.acc_h2 is not None and gm.acc_h2.tolist() == [v * CM_TO_G for v in CHAN3_CM]


# --------------------------------------------------------------------------------------------------
# Dispatch by suffix, the spec loader and `rig records show`
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["x.v1", "x.V2", "x.v1c", "x.V2C", "x.V2c"])
def test_dispatch_by_suffix_any_case(tmp_path: Path, name: str) -> None:
    path = tmp_path / name
    shutil.copy(SINE, path)
    gm = read_record_file(path)
    assert isinstance(gm, GroundMotion) and gm.provenance["format"] == "COSMOS v01.20"
    assert load_record(str(path)).acc_h.tolist() == read_cosmos(SINE).acc_h.tolist()


def run(app: typer.Typer, *args: str) -> dict:
    result = CliRunner().invoke(app, ["records", *args])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def test_cli_show_cosmos_file(app: typer.Typer, tmp_path: Path) -> None:
    data = run(app, "show", str(THREE), "--json")
    assert (data["name"], data["dt"], data["npts"]) == ("cosmos_3chan", 0.01, 20)
    assert data["pga"] == pytest.approx(18.5 * CM_TO_G, rel=1e-15)
    assert data["pga_h2"] == pytest.approx(33 * CM_TO_G, rel=1e-15)
    assert data["pga_v"] == pytest.approx(4.75 * CM_TO_G, rel=1e-15)
    assert data["provenance"]["format"] == "COSMOS v01.20"
    assert data["provenance"]["channels"]["v"]["orientation"] == "Up"
    human = CliRunner().invoke(app, ["records", "show", str(SINE)])
    assert human.exit_code == 0 and "cosmos_sine" in human.stdout and "360 deg" in human.stdout
    imported = run(app, "import", str(THREE), "--library", str(tmp_path / "lib"), "--json")
    assert imported["imported"][0]["pga_v"] == pytest.approx(4.75 * CM_TO_G, rel=1e-15)


def test_cli_show_cosmos_error_exit_2_on_stderr(app: typer.Typer, tmp_path: Path) -> None:
    bad = variant(tmp_path, SINE, "bad.V2", ("    -999.000000       5.000000", "    -999.000000    -999.000000", 1))
    result = CliRunner().invoke(app, ["records", "show", str(bad), "--json"])
    assert result.exit_code == 2 and result.stdout == ""
    assert result.stderr.startswith(f"error: {bad}:38: the sampling interval (real-header value 62) is unknown")
    assert "Traceback" not in result.output


def test_unit_without_code_in_the_data_header(tmp_path: Path) -> None:
    # some writers give no "(04)": the code comes from integer-header value 3, else the unit's name
    bare = variant(tmp_path, SINE, "bare.V2", ("units=cm/sec2(04)", "units=cm/s^2", 1))
    assert read_cosmos(bare).acc_h.tolist() == [v * CM_TO_G for v in SINE_CM]
    assert read_cosmos(bare).provenance["channels"]["h"]["unit_code"] == 4
    unknown = variant(
        tmp_path, bare, "unknown.V2", ("       2       1       4     120", "       2       1    -999     120", 1)
    )
    assert read_cosmos(unknown).acc_h.tolist() == [v * CM_TO_G for v in SINE_CM]
    assert read_cosmos(unknown).provenance["channels"]["h"]["unit_code"] is None
    nothing = variant(tmp_path, unknown, "nothing.V2", ("units=cm/s^2", "units=furlongs/fortnight", 1))
    assert error_of(read_cosmos, nothing) == (
        f"{nothing}:49: no unit code: expected 'units=<name>(<code>)' with code 02 (g), 04 (cm/s/s) or 10 (gal) "
        "in the data header or integer-header value 3"
    )
