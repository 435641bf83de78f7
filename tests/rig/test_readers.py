"""Record readers on files in each real layout: PEER .AT2 (both headers), plain text, CSV, own HDF5, H1+H2+UP.

The files under tests/data/records are written by hand in the real layouts; variants (units, exponents,
line endings, damage) are derived from them here. Values converted to g are checked against hand values,
and a few malformed-file errors are checked word for word.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import h5py
import numpy as np
import pytest

from rig.records import (
    SCHEMA,
    GroundMotion,
    RecordError,
    load_record,
    read_at2,
    read_components,
    read_csv,
    read_h5,
    read_record_file,
    read_text,
    write_record,
)

G = 9.81
DATA = Path(__file__).parents[1] / "data" / "records"
ELC180 = DATA / "RSN6_IMPVALL.I_I-ELC180.AT2"
ELC270 = DATA / "RSN6_IMPVALL.I_I-ELC270.AT2"
ELC_UP = DATA / "RSN6_IMPVALL.I_I-ELC-UP.AT2"
#: The samples of ELC180 [g], typed from the file.
ELC180_G = [0.0063, 0.0063, 0.00535, 0.00467, 0.00456, 0.00425, -0.0021, -0.012345, 0.313, -0.281, 0.0001, 0.0]


def error_of(read: object, *args: object, **kwargs: object) -> str:
    """The message of the `RecordError` that ``read(*args, **kwargs)`` raises."""
    with pytest.raises(RecordError) as info:
        read(*args, **kwargs)  # type: ignore[operator]
    return str(info.value)


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# --------------------------------------------------------------------------------------------------
# PEER .AT2
# --------------------------------------------------------------------------------------------------


def test_at2_west2_layout() -> None:
    gm = read_at2(ELC180)
    assert gm.name == "RSN6_IMPVALL.I_I-ELC180"
    assert (gm.dt, gm.npts) == (0.01, 12)
    assert gm.acc_h.tolist() == ELC180_G  # decimal text → the same doubles
    p = gm.provenance
    assert p["format"] == "PEER NGA-West2 AT2"
    assert p["title"] == "Imperial Valley-02, 5/19/1940, El Centro Array #9, 180"
    assert (p["units_in_file"], p["to_g"], p["lines"], p["npts"]) == ("G", 1.0, 7, 12)
    assert p["source_sha256"] == hashlib.sha256(ELC180.read_bytes()).hexdigest()
    assert p["path"] == str(ELC180.resolve())


def test_at2_old_nga_layout() -> None:
    gm = read_at2(DATA / "MUL009.AT2")
    assert (gm.dt, gm.npts) == (0.01, 10)
    assert gm.provenance["format"] == "PEER NGA AT2"
    assert gm.acc_h[:2].tolist() == [-0.00022, -0.00023]
    assert gm.pga == 0.416


AT2_HEADER = (
    "PEER NGA STRONG MOTION DATABASE RECORD\n"
    "Imperial Valley-06, 10/15/1979, El Centro Array #6, 230\n"
    "ACCELERATION TIME SERIES IN UNITS OF {unit}\n"
    "NPTS=      3, DT=   .0050 SEC,\n"
)


@pytest.mark.parametrize(
    ("unit", "tokens", "expected_g"),
    [
        ("G", "  .1000000E+00 -.5000000E+00  .2500000E-01", [0.1, -0.5, 0.025]),
        ("CM/S/S", "  .9810000E+02 -.4905000E+03  .2452500E+02", [0.1, -0.5, 0.025]),
        ("CM/S^2", "  .9810000E+02 -.4905000E+03  .2452500E+02", [0.1, -0.5, 0.025]),
        ("CM/SEC/SEC", "  .9810000E+02 -.4905000E+03  .2452500E+02", [0.1, -0.5, 0.025]),
        ("GAL", "  .9810000E+02 -.4905000E+03  .2452500E+02", [0.1, -0.5, 0.025]),
        ("M/S/S", "  .9810000E+00 -.4905000E+01  .2452500E+00", [0.1, -0.5, 0.025]),
        ("M/S^2", "  .9810000E+00 -.4905000E+01  .2452500E+00", [0.1, -0.5, 0.025]),
    ],
)
def test_at2_units_converted_to_g(tmp_path: Path, unit: str, tokens: str, expected_g: list[float]) -> None:
    path = write(tmp_path, "u.AT2", AT2_HEADER.format(unit=unit) + tokens + "\n")
    gm = read_at2(path)
    np.testing.assert_allclose(gm.acc_h, expected_g, rtol=1e-14, atol=0)
    assert gm.provenance["units_in_file"] == unit


@pytest.mark.parametrize("newline", ["\r\n", "\r"])
def test_at2_crlf_cr_and_fortran_d_exponents(tmp_path: Path, newline: str) -> None:
    text = AT2_HEADER.format(unit="G") + "  .1000000D+00 -.5000000d+00\n  .2500000D-01\n"
    path = tmp_path / "d.AT2"
    path.write_bytes(text.replace("\n", newline).encode())
    gm = read_at2(path)
    assert gm.acc_h.tolist() == [0.1, -0.5, 0.025]
    assert gm.provenance["lines"] == 6


def test_at2_given_dt_and_units_must_agree_with_header() -> None:
    assert read_at2(ELC180, dt=0.01, units="g").dt == 0.01
    assert error_of(read_at2, ELC180, dt=0.02) == (
        f"{ELC180}:4: the file gives dt = 0.01 s but dt = 0.02 s was given; expected the same dt"
    )
    assert error_of(read_at2, ELC180, units="gal") == (
        f"{ELC180}:3: the file gives the unit g but cm/s/s was given; expected the same unit"
    )


def _west2(tmp_path: Path, npts: int, rows: list[str]) -> Path:
    header = AT2_HEADER.format(unit="G").replace("NPTS=      3", f"NPTS={npts:>7d}")
    return write(tmp_path, "w.AT2", header + "\n".join(rows) + "\n")


ROW = "  .1000000E-02 -.2000000E-02  .3000000E-02 -.4000000E-02  .5000000E-02"


def test_error_truncated_at2_word_for_word(tmp_path: Path) -> None:
    path = _west2(tmp_path, 12, [ROW, "  .1000000E-02 -.2000000E-02  .3000000E-02"])
    assert error_of(read_at2, path) == (
        f"{path}:6: truncated data: line 4 declares NPTS=12 but the file holds 8 values (lines 5-6); "
        "expected 12 values"
    )


def test_error_npts_disagreeing_word_for_word(tmp_path: Path) -> None:
    path = _west2(tmp_path, 10, [ROW, ROW, ROW])
    assert error_of(read_at2, path) == (
        f"{path}:7: extra data: line 4 declares NPTS=10 but the file holds 15 values (lines 5-7); "
        "expected 10 values"
    )


def test_error_non_numeric_token_word_for_word(tmp_path: Path) -> None:
    path = _west2(tmp_path, 10, [ROW, "  .1000000E-02  .12E-0x  .3000000E-02 -.4000000E-02  .5000000E-02"])
    assert error_of(read_at2, path) == (
        f"{path}:6: token 2 of the line, '.12E-0x', is not a number; expected a decimal number such as -1.25E-02"
    )


def test_error_overflowing_and_implausible_values_word_for_word(tmp_path: Path) -> None:
    path = _west2(tmp_path, 2, ["  .1000000E-02  1E999"])
    assert error_of(read_at2, path) == (
        f"{path}:5: token 2 of the line, '1E999', overflows a 64-bit float; expected |value| < 1.8E+308"
    )
    path = _west2(tmp_path, 2, ["  .1000000E-02  .9810000E+03"])
    assert error_of(read_at2, path) == (
        f"{path}:5: token 2 of the line, '.9810000E+03' G = 981 g, is not a plausible ground acceleration; "
        "expected |acceleration| <= 100 g (is the unit right?)"
    )


def test_error_empty_binary_and_non_utf8_files_word_for_word(tmp_path: Path) -> None:
    empty = write(tmp_path, "empty.AT2", "")
    assert error_of(read_at2, empty) == (
        f"{empty}:1: the file is empty; expected a PEER .AT2 file: a 4-line header (title, event, units, "
        "NPTS/DT) and the samples"
    )
    binary = tmp_path / "binary.AT2"
    binary.write_bytes(b"\x89HDF\r\n\x1a\n\x00\x00\x00")
    assert error_of(read_at2, binary) == (
        f"{binary}:3: NUL byte at column 1; expected a text file (this looks like a binary file)"
    )
    latin1 = tmp_path / "latin1.AT2"
    latin1.write_bytes(ELC180.read_bytes().replace(b"Imperial", b"Imp\xe9rial"))
    assert error_of(read_at2, latin1) == (
        f"{latin1}:2: byte 0xe9 at column 4 is not UTF-8 text; expected a UTF-8 text file"
    )


def test_utf8_bom_is_dropped_and_counted_in_the_checksum(tmp_path: Path) -> None:
    path = tmp_path / "bom.AT2"
    raw = b"\xef\xbb\xbf" + ELC180.read_bytes()
    path.write_bytes(raw)
    gm = read_at2(path)
    assert gm.acc_h.tolist() == ELC180_G
    assert gm.provenance["source_sha256"] == hashlib.sha256(raw).hexdigest()


# --------------------------------------------------------------------------------------------------
# Plain text
# --------------------------------------------------------------------------------------------------


def test_text_one_column_with_header_settings() -> None:
    path = DATA / "ELC180_gal.txt"
    gm = read_text(path)
    np.testing.assert_allclose(gm.acc_h, [0.0063, -0.01, 0.1, 0.3125, -0.281, 0.0], rtol=1e-14)
    assert gm.dt == 0.01
    p = gm.provenance
    assert (p["format"], p["units_in_file"], p["units_from"], p["dt_from"]) == (
        "plain text, acceleration", "cm/s/s", "file", "file",
    )
    assert p["to_g"] == 0.01 / G and p["lines"] == 11 and p["npts"] == 6


def test_text_one_column_without_header_needs_dt_and_units(tmp_path: Path) -> None:
    path = write(tmp_path, "bare.txt", "0.981\n-1.962\n0\n")
    gm = read_text(path, dt=0.02, units="m/s^2")
    np.testing.assert_allclose(gm.acc_h, [0.1, -0.2, 0.0], rtol=1e-15)
    assert gm.dt == 0.02
    assert (gm.provenance["units_from"], gm.provenance["dt_from"]) == ("given", "given")
    assert error_of(read_text, path, units="g") == (
        f"{path}: no time step: a one-column file needs a '# dt = …' line or a given dt (--dt S)"
    )
    assert error_of(read_text, path, dt=0.02) == (
        f"{path}: no acceleration unit: expected a '# units = …' line in the file or a given unit "
        "(--units g|cm/s/s|m/s/s)"
    )


def test_text_two_columns_dt_from_time_column(tmp_path: Path) -> None:
    gm = read_text(DATA / "two_column.dat", units="g")
    assert gm.dt == 0.005
    assert gm.acc_h.tolist() == [0.01, -0.025, 0.4, -0.35, 0.005]
    assert (gm.provenance["dt_from"], gm.provenance["t0"]) == ("time column", 0.0)

    later = write(tmp_path, "later.dat", "# units = g\n# dt = 0.1\n12.3 0.1\n12.4 0.2\n12.5 0.3\n")
    gm = read_text(later)
    assert (gm.dt, gm.provenance["t0"], gm.npts) == (0.1, 12.3, 3)  # dt rounded to the decimal step


def test_text_header_and_given_dt_must_match_time_column(tmp_path: Path) -> None:
    path = write(tmp_path, "t.dat", "# dt = 0.02 s\n# units = g\n0 0.1\n0.01 0.2\n")
    assert error_of(read_text, path) == (
        f"{path}:1: dt = 0.02 s but the time column is spaced 0.01 s; expected the same dt"
    )
    path = write(tmp_path, "t2.dat", "# units = g\n0 0.1\n0.01 0.2\n")
    assert error_of(read_text, path, dt=0.005) == (
        f"{path}:2: the file gives dt = 0.01 s but dt = 0.005 s was given; expected the same dt"
    )


def test_error_uneven_time_column_word_for_word(tmp_path: Path) -> None:
    path = write(tmp_path, "uneven.dat", "0 0.1\n0.01 0.2\n0.02 0.1\n0.035 0.4\n0.04 0.0\n")
    assert error_of(read_text, path, units="g") == (
        f"{path}:4: uneven time column: t = 0.035 s, expected 0.03 s (t0 + 3 x 0.01 s, within 1% of dt)"
    )
    back = write(tmp_path, "back.dat", "0 0.1\n0.01 0.2\n0.01 0.1\n")
    assert error_of(read_text, back, units="g") == (
        f"{back}:3: time 0.01 s does not increase (line 2 has 0.01 s); expected increasing, evenly spaced times"
    )


def test_time_column_rounded_within_tolerance(tmp_path: Path) -> None:
    # dt = 1/98 s printed with 5 decimals: each time within 0.05 % of dt of the even grid
    times = [f"{i / 98:.5f}" for i in range(2000)]
    path = write(tmp_path, "rounded.dat", "".join(f"{t} 0.0\n" for t in times))
    assert read_text(path, units="g").dt == pytest.approx(1 / 98, rel=1e-7)
    # printed with 3 decimals the rounding (up to 5 % of dt) is refused, at the first time off the grid
    coarse = write(tmp_path, "coarse.dat", "".join(f"{i / 98:.3f} 0.0\n" for i in range(2000)))
    assert error_of(read_text, coarse, units="g").startswith(f"{coarse}:2: uneven time column: t = 0.01 s, expected")


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        ("# dt = -0.01 s\n0.1\n", 1,
         "dt = '-0.01 s' is not a record's time step; expected 1e-05 s to 1 s, such as 0.01 s"),
        ("# units = g\n# dt = 0 s\n0.1\n", 2,
         "dt = '0 s' is not a record's time step; expected 1e-05 s to 1 s, such as 0.01 s"),
        ("# dt = 10 min\n0.1\n", 1, "dt '10 min' is not a time in seconds; expected e.g. '# dt = 0.01 s'"),
        ("# units = furlong/s2\n0.1\n", 1,
         "unknown acceleration unit 'furlong/s2'; expected one of g, cm/s/s (= gal, cm/s^2), m/s/s (m/s^2), mm/s/s"),
        ("# dt = 0.01\n# DT: 0.02\n0.1\n", 2, "second 'dt' setting (line 1 gave one); expected one"),
        ("# npts = 3\n# dt = 0.01\n# units = g\n0.1\n0.2\n", 1,
         "truncated data: npts = 3 but the file holds 2 samples (lines 4-5); expected 3 samples"),
        ("# dt = 0.01\n# units = g\n0.1\n0.2 0.3\n", 4, "2 column(s); expected 1 like line 3, the first data line"),
        ("# dt = 0.01\n# units = g\n0.1 0.2 0.3\n", 3,
         "3 columns; expected 1 (acceleration) or 2 (time [s], acceleration) (use a CSV file with named columns "
         "for more channels)"),
        ("# dt = 0.01\n# units = g\n0.1\nnan\n", 4, "the acceleration is 'nan'; expected a finite number"),
        ("# just a comment\n\n", 2,
         "no samples; expected samples: one column (acceleration) or two (time [s], acceleration) a line, "
         "'#' comments"),
    ],
)
def test_text_errors_word_for_word(tmp_path: Path, text: str, line: int, message: str) -> None:
    path = write(tmp_path, "bad.txt", text)
    assert error_of(read_text, path) == f"{path}:{line}: {message}"


# --------------------------------------------------------------------------------------------------
# CSV
# --------------------------------------------------------------------------------------------------


def test_csv_unit_in_header() -> None:
    gm = read_csv(DATA / "ELC180_cm.csv")
    np.testing.assert_allclose(gm.acc_h, [0.0063, -0.01, 0.1, -0.281, 0.0], rtol=1e-14)
    assert gm.dt == 0.01 and gm.acc_v is None and gm.acc_h2 is None
    p = gm.provenance
    assert (p["format"], p["columns"], p["units_in_file"]) == ("CSV", ["t [s]", "acceleration [cm/s2]"], "cm/s2")


def test_csv_three_components() -> None:
    gm = read_csv(DATA / "three_components.csv")
    assert gm.dt == 0.005
    assert gm.acc_h.tolist() == [0.0063, -0.313, 0.0]
    assert gm.acc_h2 is not None and gm.acc_h2.tolist() == [-0.0025, 0.215, -0.0005]
    assert gm.acc_v is not None and gm.acc_v.tolist() == [0.001, 0.18, 0.0]


@pytest.mark.parametrize(
    ("header", "to_g"),
    [
        ("time_s,acc_g", 1.0),
        ("t [s],acceleration [cm/s2]", 0.01 / G),
        ("Time (s),Acc-H (m/s^2)", 1 / G),
        ("t,acc_gal", 0.01 / G),
        ('"time [sec]","acc_h1_cm_s_s"', 0.01 / G),
        ("T_S,ACCEL_MM_S2", 0.001 / G),
    ],
)
def test_csv_column_names_and_units(tmp_path: Path, header: str, to_g: float) -> None:
    path = write(tmp_path, "n.csv", f"{header}\n0,98.1\n0.02,-49.05\n")
    gm = read_csv(path)
    np.testing.assert_allclose(gm.acc_h, np.array([98.1, -49.05]) * to_g, rtol=1e-15)
    assert gm.dt == 0.02


def test_csv_without_time_column_uses_given_or_header_dt(tmp_path: Path) -> None:
    path = write(tmp_path, "a.csv", "acc_h,acc_v\n0.1,0.0\n0.2,-0.1\n")
    gm = read_csv(path, dt=0.01, units="g")
    assert (gm.dt, gm.acc_v.tolist() if gm.acc_v is not None else None) == (0.01, [0.0, -0.1])
    with_header = write(tmp_path, "b.csv", "# dt = 0.005 s\n# units = g\nacc\n0.1\n")
    assert read_csv(with_header).dt == 0.005


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        ("t,vel_cm_s\n0,1\n", 1,
         "column 2, 'vel_cm_s', is not a record column; expected t/time [s] and acc (or acc_h), acc_h2, acc_v, "
         "each with an optional unit (e.g. 'time_s,acc_g' or 't [s],acceleration [cm/s2]')"),
        ("t [ms],acc_g\n0,1\n", 1, "column 1, 't [ms]': unknown unit 'ms'; expected s"),
        ("t,acc_g,acc_h_g\n0,1,1\n", 1,
         "columns 2 and 3 are both the first horizontal channel; expected each channel once"),
        ("t,acc_v_g\n0,1\n", 1,
         "no first horizontal acceleration column (acc or acc_h); expected t/time [s] and acc (or acc_h), acc_h2, "
         "acc_v, each with an optional unit (e.g. 'time_s,acc_g' or 't [s],acceleration [cm/s2]')"),
        ("t,acc_g,acc_v_gal\n0,1,1\n", 1, "the acceleration columns have different units (g, gal); expected one unit"),
        ("t,acc_g\n0,1\n0.01\n", 3, "1 cells; expected 2 like the header (line 1)"),
        ("t,acc_g\n0,1\n0.01,x\n", 3,
         "column 2 (acc_g), 'x', is not a number; expected a decimal number such as -1.25E-02"),
        ("# units = cm/s/s\nt,acc_g\n0,1\n0.01,2\n", 1,
         "units = cm/s/s but the header (line 2) says g; expected the same unit"),
        ("# npts = 3\nt,acc_g\n0,1\n\n0.01,2\n", 1,
         "truncated data: npts = 3 but the file holds 2 samples (lines 3-5); expected 3 samples"),
        ("# dt = 0.02\nt,acc_g\n0,1\n0.01,2\n", 1,
         "dt = 0.02 s but the time column is spaced 0.01 s; expected the same dt"),
        ("t,acc_g\n", 1, "no data rows after the header (line 1); expected a CSV record: a header row such as "
         "'time_s,acc_g' and one sample a row"),
    ],
)
def test_csv_errors_word_for_word(tmp_path: Path, text: str, line: int, message: str) -> None:
    path = write(tmp_path, "bad.csv", text)
    assert error_of(read_csv, path) == f"{path}:{line}: {message}"


def test_csv_unit_missing(tmp_path: Path) -> None:
    path = write(tmp_path, "nounit.csv", "time,acc\n0,1\n0.01,2\n")
    assert error_of(read_csv, path) == (
        f"{path}:1: no acceleration unit: expected a unit in the column names (acc_g, acc [cm/s2]), "
        "a '# units = …' line or a given unit (--units)"
    )
    assert read_csv(path, units="gal").acc_h.tolist() == pytest.approx([0.01 / G, 0.02 / G], rel=1e-15)


# --------------------------------------------------------------------------------------------------
# The project's own HDF5 record file
# --------------------------------------------------------------------------------------------------


def test_h5_round_trip_bit_for_bit(tmp_path: Path) -> None:
    rng = np.random.default_rng(20240611)
    motion = GroundMotion(
        name="NORTHR/MUL009 (scaled)", dt=0.0049999999999999996, acc_h=rng.normal(0, 0.1, 1001),
        acc_h2=rng.normal(0, 0.1, 1001), acc_v=rng.normal(0, 0.05, 1001),
        provenance={"source": "test", "nested": {"a": [1, 2.5, "x"]}, "note": "Düzce ✓"},
    )
    path = write_record(motion, tmp_path / "r.h5")
    back = read_h5(path)
    assert back.name == motion.name and back.dt == motion.dt
    for channel in ("acc_h", "acc_h2", "acc_v"):
        assert getattr(back, channel).tobytes() == getattr(motion, channel).tobytes()
    stored_in = back.provenance.pop("stored_in")
    assert back.provenance == motion.provenance
    assert stored_in == {
        "path": str(path.resolve()), "schema": SCHEMA, "file_sha256": hashlib.sha256(path.read_bytes()).hexdigest()
    }
    assert load_record(str(path)).acc_h.tobytes() == motion.acc_h.tobytes()


def test_h5_layout_as_documented(tmp_path: Path) -> None:
    path = write_record(read_csv(DATA / "ELC180_cm.csv"), tmp_path / "elc.hdf5")
    raw = path.read_bytes()
    assert raw[:512] == (
        f"{SCHEMA}\nsha256 {hashlib.sha256(raw[512:]).hexdigest()}\n".encode().ljust(512, b"\0")
    )
    with h5py.File(path, "r") as h5:
        assert h5.userblock_size == 512
        assert dict(h5.attrs) | {"provenance": None} == {
            "schema": SCHEMA, "name": "ELC180_cm", "dt": 0.01, "units": "g", "provenance": None,
        }
        assert json.loads(h5.attrs["provenance"])["format"] == "CSV"
        assert sorted(h5) == ["acc_h"]
        assert h5["acc_h"].dtype == np.dtype("<f8") and h5["acc_h"].attrs["units"] == "g"


def test_h5_write_never_overwrites_unless_asked(tmp_path: Path) -> None:
    first, second = read_at2(ELC180), read_at2(ELC270)
    path = write_record(first, tmp_path / "r.h5")
    before = path.read_bytes()
    assert error_of(write_record, second, path) == f"{path}: already exists; expected a new file name (or replace it)"
    assert path.read_bytes() == before
    write_record(second, path, replace=True)
    assert read_h5(path).acc_h.tolist() == second.acc_h.tolist()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.h5"]  # no temporary files left


def test_h5_damaged_or_foreign_files(tmp_path: Path) -> None:
    path = write_record(read_at2(ELC180), tmp_path / "r.h5")
    raw = bytearray(path.read_bytes())
    raw[-20] ^= 0x01
    damaged = tmp_path / "damaged.h5"
    damaged.write_bytes(bytes(raw))
    assert error_of(read_h5, damaged) == (
        f"{damaged}: the checksum in the user block does not match the file (changed or damaged since it was "
        "written); expected a shaketable-rig record file (schema shaketable-rig/record/1) written by "
        "`rig records import`"
    )
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as h5:
        h5["acc_h"] = np.zeros(3)
    assert error_of(read_h5, foreign) == (
        f"{foreign}: no 'shaketable-rig/record/1' user block at byte 0; expected a shaketable-rig record file "
        "(schema shaketable-rig/record/1) written by `rig records import`"
    )
    assert error_of(read_h5, path, dt=0.02) == (
        f"{path}: the file gives dt = 0.01 s but dt = 0.02 s was given; expected the same dt"
    )


def test_h5_refuses_provenance_that_is_not_json(tmp_path: Path) -> None:
    motion = GroundMotion(name="x", dt=0.01, acc_h=[0.0, 0.1], provenance={"bad": math.nan})
    message = error_of(write_record, motion, tmp_path / "x.h5")
    assert message.startswith("record 'x': provenance is not JSON-serialisable")
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------------------------------
# H1+H2[+UP] and the spec dispatcher
# --------------------------------------------------------------------------------------------------


def test_pair_plus_vertical_from_spec() -> None:
    spec = f"{ELC180}+{ELC270}+{ELC_UP}"
    gm = load_record(spec)
    assert gm.name == "RSN6_IMPVALL.I_I-ELC180+RSN6_IMPVALL.I_I-ELC270+RSN6_IMPVALL.I_I-ELC-UP"
    assert (gm.dt, gm.npts) == (0.01, 12)
    assert gm.acc_h.tolist() == ELC180_G
    assert gm.acc_h2 is not None and gm.acc_h2.tolist() == read_at2(ELC270).acc_h.tolist()
    assert gm.acc_v is not None and gm.acc_v.tolist() == read_at2(ELC_UP).acc_h.tolist()
    assert gm.pga_h2 == 0.215 and gm.pga_v == 0.18
    p = gm.provenance
    assert p["format"] == "component set H1+H2+UP"
    assert p["files"] == [str(ELC180), str(ELC270), str(ELC_UP)]
    assert sorted(p["components"]) == ["h", "h2", "v"]
    assert p["components"]["v"]["source_sha256"] == hashlib.sha256(ELC_UP.read_bytes()).hexdigest()
    json.dumps(p, allow_nan=False)

    pair = load_record(f" {ELC180} + {ELC270} ")
    assert pair.acc_v is None and pair.provenance["format"] == "component set H1+H2"


def test_pair_errors_name_both_files(tmp_path: Path) -> None:
    short = write(tmp_path, "ELC270-short.AT2", ELC270.read_text().replace("NPTS=     12", "NPTS=     10")
                  .replace("  .1000000E-02 -.5000000E-03\n", ""))
    assert error_of(read_components, [ELC180, short]) == (
        f"{ELC180} has 12 samples but {short} has 10; expected the same number of samples in every component"
    )
    coarse = write(tmp_path, "ELC270-coarse.AT2", ELC270.read_text().replace(".0100 SEC", ".0200 SEC"))
    assert error_of(read_components, [ELC180, coarse]) == (
        f"{ELC180} has dt = 0.01 s but {coarse} has dt = 0.02 s; expected the components of one record to share dt"
    )
    assert error_of(load_record, f"{ELC_UP}+{ELC180}") == (
        f"{ELC_UP}: horizontal component 1 is named like a vertical one (the file name "
        "'RSN6_IMPVALL.I_I-ELC-UP.AT2'); expected H1+H2+UP with the vertical component last"
    )
    three = DATA / "three_components.csv"
    assert error_of(read_components, [three, ELC180]) == (
        f"{three}: holds several components; expected one component per file in H1+H2[+UP]"
    )
    assert error_of(load_record, f"{ELC180}+") == (
        f"'{ELC180}+': expected H1+H2 or H1+H2+UP, two or three record files joined by '+'"
    )


def test_path_with_plus_that_exists_is_one_file(tmp_path: Path) -> None:
    path = tmp_path / "a+b.AT2"
    path.write_bytes(ELC180.read_bytes())
    assert load_record(str(path)).name == "a+b"


@pytest.mark.parametrize(
    ("name", "kwargs"),
    [("x.at2", {}), ("x.Txt", {"dt": 0.01, "units": "g"}), ("x.DAT", {"dt": 0.01, "units": "g"}),
     ("x.acc", {"dt": 0.01, "units": "g"}), ("x.CSV", {"units": "g"})],
)
def test_dispatch_by_suffix_any_case(tmp_path: Path, name: str, kwargs: dict) -> None:
    source = {"at2": ELC180.read_text(), "txt": "0.1\n", "dat": "0.1\n", "acc": "0.1\n", "csv": "acc\n0.1\n"}
    path = write(tmp_path, name, source[name.rsplit(".", 1)[1].lower()])
    kwargs = kwargs | ({"dt": 0.01} if name.endswith("CSV") else {})
    assert isinstance(read_record_file(path, **kwargs), GroundMotion)


def test_dispatch_errors(tmp_path: Path) -> None:
    other = write(tmp_path, "x.sac", "whatever")
    assert error_of(load_record, str(other)) == (
        f"{other}: unsupported record file type '.sac'; expected one of .at2, .txt, .dat, .acc, .csv, .h5, .hdf5, "
        ".v1, .v2, .v1c, .v2c"
    )
    assert error_of(load_record, "fema-farfield:NORTHR/MUL009", dt=0.01) == (
        "'fema-farfield:NORTHR/MUL009' has its own dt and units; expected dt/units only with a record file"
    )
    assert error_of(load_record, str(ELC180), dt=-0.01) == (
        "the given dt must be a number of seconds from 1e-05 to 1, got -0.01"
    )
    assert error_of(load_record, str(ELC180), units="furlong") == (
        "unknown acceleration unit 'furlong'; expected one of g, cm/s/s (= gal, cm/s^2), m/s/s (m/s^2), mm/s/s"
    )
