"""Issue 16, records: the component a file holds (COSMOS orientation codes, PEER line 2 and file name,
NGA-East channel names) in the right place or a clear refusal; CSMIP end-of-data lines; CSMIP/DMG files
named in the error; CR CR LF line ends; peaks with significant digits; one-line errors on a non-terminal.

Files are variants of the real-layout files in tests/data/records (see test_cosmos.py and test_readers.py).
"""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from rig.records import RecordError, RecordWarning, load_record, read_at2, read_components, read_cosmos

DATA = Path(__file__).parents[1] / "data" / "records"
SINE = DATA / "cosmos_sine.V2"
H1, H2, UP = (DATA / f"RSN6_IMPVALL.I_I-{name}.AT2" for name in ("ELC180", "ELC270", "ELC-UP"))
REPO = Path(__file__).resolve().parents[2]


def variant(tmp_path: Path, source: Path, name: str, *changes: tuple[str, str, int]) -> Path:
    """A copy of ``source`` named ``name`` with each (old, new, count) replaced; ``old`` must occur ``count`` times."""
    text = source.read_text()
    for old, new, count in changes:
        assert text.count(old) == count, (old, text.count(old))
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text)
    return path


def error_of(read: object, *args: object, **kwargs: object) -> str:
    with pytest.raises(RecordError) as info:
        read(*args, **kwargs)  # type: ignore[operator]
    return str(info.value)


# ---------------------------------------------------------------------------------------------------------
# COSMOS orientation codes
# ---------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("code", "meaning"), [(400, "Up"), (401, "Down"), (402, "Vertical")])
def test_a_lone_cosmos_vertical_is_refused_unless_accepted(tmp_path: Path, code: int, meaning: str) -> None:
    path = variant(tmp_path, SINE, f"vertical{code}.V2", ("     360", f"{code:8d}", 1))
    message = error_of(load_record, str(path))
    assert message.startswith(f"{path}:20: holds a vertical component (COSMOS orientation code {code}: {meaning}")
    assert "--accept-vertical" in message
    motion = load_record(str(path), accept_vertical=True)
    expected = read_cosmos(SINE).acc_h * (-1.0 if code == 401 else 1.0)  # Down is negated to read positive up
    np.testing.assert_array_equal(motion.acc_h, expected)
    assert motion.provenance["component"]["kind"] == "vertical"


def test_a_cosmos_vertical_is_refused_in_a_horizontal_place_and_a_horizontal_in_the_vertical_one(
    tmp_path: Path,
) -> None:
    up = variant(tmp_path, SINE, "chan_a.V2", ("     360", "     400", 1))
    east = variant(tmp_path, SINE, "chan_e.V2", ("     360", "      90", 1))
    north = variant(tmp_path, SINE, "chan_n.V2", ("     360", "     360", 1))
    message = error_of(read_components, [up, east])
    assert message.startswith(f"{up}:20: holds a vertical component (COSMOS orientation code 400: Up, chan 1)")
    assert "given as the first horizontal of H1+H2[+UP]" in message
    message = error_of(read_components, [north, east, north])
    assert message.startswith(f"{north}:20: holds a horizontal component (COSMOS orientation code 360: 360 deg")
    assert "given as the vertical of H1+H2+UP" in message
    motion = read_components([north, east, up])
    np.testing.assert_array_equal(motion.acc_v, read_cosmos(SINE).acc_h)


@pytest.mark.parametrize(("code", "shown"), [(0, "0 (not a COSMOS azimuth"), (2000, "Other (see comments)"),
                                             (-999, "unknown")])
def test_an_unknown_cosmos_orientation_is_read_with_a_warning(tmp_path: Path, code: int, shown: str) -> None:
    path = variant(tmp_path, SINE, f"other{code}.V2", ("     360", f"{code:8d}", 1))
    with pytest.warns(RecordWarning) as caught:
        motion = load_record(str(path))
    assert len(caught) == 1
    text = str(caught[0].message)
    assert text.startswith(f"{path}:20: chan 1 has orientation {shown}")
    assert motion.provenance["component"]["kind"] == "unknown"


def test_a_known_orientation_gives_no_warning() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_record(str(SINE)).provenance["component"]["kind"] == "horizontal"


# ---------------------------------------------------------------------------------------------------------
# PEER line 2 and file names, NGA-East channel names
# ---------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("word", ["UP", "DWN", "V", "HNZ", "hhz"])
def test_a_peer_vertical_named_only_on_line_2_is_refused_in_a_horizontal_place(tmp_path: Path, word: str) -> None:
    path = variant(tmp_path, UP, "RSN6_IMPVALL.I_I-ELC.AT2", ("Array #9, UP", f"Array #9, {word}", 1))
    message = error_of(read_components, [path, H2])
    assert message.startswith(f"{path}:2: holds a vertical component (PEER line 2 component {word!r}")
    message = error_of(load_record, str(path))
    assert "expected a horizontal record to drive surge" in message
    assert load_record(str(path), accept_vertical=True).provenance["component"]["kind"] == "vertical"


def test_an_nga_east_channel_name_in_the_file_name_is_read(tmp_path: Path) -> None:
    path = variant(tmp_path, H1, "NGA_East_0001_ST01.HNZ.AT2", ("Array #9, 180", "Array #9, X", 1))
    assert read_at2(path).provenance["component"]["said_by"] == ("the file name 'NGA_East_0001_ST01.HNZ.AT2', SEED "
                                                                 "channel HNZ: orientation Z, vertical")
    assert error_of(load_record, str(path)).startswith(f"{path}: holds a vertical component (the file name")
    east = variant(tmp_path, H1, "NGA_East_0001_ST01.HNE.AT2", ("Array #9, 180", "Array #9, HNE", 1))
    assert read_at2(east).provenance["component"]["kind"] == "horizontal"


def test_a_peer_horizontal_in_the_vertical_place_is_refused() -> None:
    message = error_of(read_components, [H1, H2, H1])
    assert message.startswith(f"{H1}:2: holds a horizontal component (PEER line 2 component '180')")


def test_a_peer_file_whose_name_and_line_2_disagree_is_refused(tmp_path: Path) -> None:
    path = variant(tmp_path, H1, "RSN6-ELC-UP.AT2", ("Array #9, 180", "Array #9, 180", 1))
    assert error_of(read_at2, path) == (
        f"{path}:2: line 2 gives the horizontal component '180' but the file name 'RSN6-ELC-UP.AT2' names a "
        "vertical one; expected the two to agree (rename the file or fix line 2)"
    )


def test_the_pair_with_its_vertical_last_still_reads() -> None:
    motion = load_record(f"{H1}+{H2}+{UP}")
    assert motion.acc_v is not None and motion.provenance["components"]["v"]["component"]["kind"] == "vertical"


# ---------------------------------------------------------------------------------------------------------
# CSMIP end lines, CSMIP/DMG files, CR CR LF
# ---------------------------------------------------------------------------------------------------------


def test_csmip_style_end_of_data_lines_are_read(tmp_path: Path) -> None:
    path = variant(tmp_path, SINE, "csmip_end.V2", ("End-of-data for Chan  1 acceleration",
                                                    "/&  ----------  End of data for channel  1  ----------", 1))
    np.testing.assert_array_equal(read_cosmos(path).acc_h, read_cosmos(SINE).acc_h)
    early = variant(tmp_path, path, "csmip_short.V2", ("   0.000000e+00   3.031460e+01\n", "", 1))
    assert "truncated data: 'End-of-data' after 20 values; expected 22 values" in error_of(read_cosmos, early)


@pytest.mark.parametrize(("suffix", "first"), [
    (".V1", "Uncorrected Accelerogram Data             Processed: 02/13/12, CGS  146be002"),
    (".V2", "CORRECTED ACCELEROGRAM DATA           (PROCESSED: 94/02/10)"),
    (".V3", "RESPONSE AND FOURIER AMPLITUDE SPECTRA"),
])
def test_a_csmip_dmg_file_is_named_and_the_cosmos_files_pointed_to(tmp_path: Path, suffix: str, first: str) -> None:
    path = tmp_path / f"CE24278{suffix}"
    path.write_text(f"{first}\nNorthridge Earthquake                 January 17, 1994 04:31 PST\n  0.7 ..........\n")
    if suffix == ".V3":
        path = path.rename(tmp_path / "CE24278.V2")  # a spectra file saved under a record suffix
    message = error_of(load_record, str(path))
    assert message.startswith(f"{path}:1: this is a CSMIP/DMG-format file ({first.strip()[:67]!r}"[:-1])
    assert "COSMOS files (.V1C/.V2C) from CESMD" in message


def test_cr_cr_lf_line_ends_read_as_one_line_break_and_errors_give_the_editor_line(tmp_path: Path) -> None:
    raw = H1.read_bytes().replace(b"\n", b"\r\r\n")
    path = tmp_path / "crcrlf-ELC180.AT2"
    path.write_bytes(raw)
    np.testing.assert_array_equal(read_at2(path).acc_h, read_at2(H1).acc_h)
    bad = tmp_path / "crcrlf-bad-ELC180.AT2"
    lines = raw.split(b"\r\r\n")
    lines[5] = lines[5].replace(b"E", b"Q", 1)  # the 6th line an editor shows
    bad.write_bytes(b"\r\r\n".join(lines))
    assert error_of(read_at2, bad).startswith(f"{bad}:6: ")
    cosmos = tmp_path / "crcrlf.V2"
    cosmos.write_bytes(SINE.read_bytes().replace(b"\n", b"\r\r\n"))
    np.testing.assert_array_equal(read_cosmos(cosmos).acc_h, read_cosmos(SINE).acc_h)


# ---------------------------------------------------------------------------------------------------------
# The CLI: peaks, --accept-vertical, one-line errors, warnings
# ---------------------------------------------------------------------------------------------------------


def test_records_show_prints_small_peaks_with_significant_digits(tmp_path: Path) -> None:
    from rig.cli import app

    path = tmp_path / "tiny.txt"
    path.write_text("# dt = 0.01\n# units = g\n" + "\n".join(f"{v:.3e}" for v in (0.0, 2.7e-6, -1.1e-6, 0.0)) + "\n")
    result = CliRunner().invoke(app, ["records", "show", str(path)])
    assert result.exit_code == 0, result.output
    assert "2.7e-06" in result.output and "0.0000" not in result.output


def test_the_cli_takes_a_lone_vertical_only_with_accept_vertical(tmp_path: Path) -> None:
    from rig.cli import app

    refused = CliRunner().invoke(app, ["records", "show", str(UP)])
    assert refused.exit_code == 2 and "holds a vertical component" in refused.output
    shown = CliRunner().invoke(app, ["records", "show", str(UP), "--accept-vertical", "--json"])
    assert shown.exit_code == 0, shown.output


def _rig(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rig.cli", *args], capture_output=True, text=True, cwd=REPO,
                          timeout=120)


@pytest.mark.integration
def test_errors_and_warnings_are_one_line_each_when_stderr_is_not_a_terminal(tmp_path: Path) -> None:
    bad = variant(tmp_path, H1, "a-rather-long-file-name-for-the-record-of-the-imperial-valley-ELC180.AT2",
                  ("IN UNITS OF G", "IN UNITS OF FURLONGS PER FORTNIGHT SQUARED", 1))
    result = _rig("prepare", str(bad))
    assert result.returncode == 2
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and len(lines[0]) > 80, result.stderr
    assert lines[0].startswith(f"error: {bad}:3: unknown acceleration unit 'FURLONGS'")
    other = variant(tmp_path, SINE, "a-long-name-so-that-the-warning-would-wrap-at-eighty-columns.V2",
                    ("     360", "    2000", 1))
    result = _rig("records", "show", str(other), "--json")
    assert result.returncode == 0
    assert result.stderr.splitlines() == [f"warning: {other}:20: chan 1 has orientation Other (see comments) "
                                          "(integer-header value 54); its direction is unknown, check it before "
                                          "playing it"]


@pytest.mark.integration
def test_usage_errors_are_one_plain_line_when_stderr_is_not_a_terminal() -> None:
    result = _rig("prepare", "--no-such-option", "x.AT2")
    assert result.returncode == 2
    assert "Error: No such option: --no-such-option" in result.stderr.splitlines(), result.stderr
    assert "╭" not in result.stderr and "│" not in result.stderr


def test_the_library_imports_a_lone_vertical_only_when_accepted(tmp_path: Path) -> None:
    from rig.records import import_records, load_library_record

    library = tmp_path / "library"
    assert "holds a vertical component" in error_of(import_records, [str(UP)], directory=library)
    assert not library.exists() or not list(library.iterdir())  # nothing stored
    (entry,) = import_records([str(UP)], directory=library, accept_vertical=True)
    assert load_library_record(entry.name, library).provenance["component"]["kind"] == "vertical"


# ---------------------------------------------------------------------------------------------------------
# SEED channel codes with location codes (issue 25): band, instrument, orientation Z/N/E/1/2/3, every format
# ---------------------------------------------------------------------------------------------------------

CSV3 = DATA / "three_components.csv"
TEXT = DATA / "ELC180_gal.txt"


@pytest.mark.parametrize("word", ["BHZ00", "BHZ.00", "00.BHZ", "HNZ-10", "HNZ --", "HN3", "hnz"])
def test_a_seed_vertical_with_its_location_on_line_2_is_a_vertical(tmp_path: Path, word: str) -> None:
    path = variant(tmp_path, H1, "RSN6-ELC.AT2", ("Array #9, 180", f"Array #9, {word}", 1))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        entry = read_at2(path).provenance["component"]
    assert (entry["kind"], entry["line"]) == ("vertical", 2)
    assert entry["said_by"].startswith(f"PEER line 2 component {word!r}, SEED channel ")
    assert error_of(load_record, str(path)).startswith(f"{path}:2: holds a vertical component")
    assert error_of(read_components, [path, H2]).startswith(f"{path}:2: holds a vertical component")


@pytest.mark.parametrize("word", ["HN1", "HN2.00", "HNE", "BHN10", "00.HHE", "HNT"])
def test_a_seed_horizontal_with_its_location_on_line_2_is_a_horizontal(tmp_path: Path, word: str) -> None:
    path = variant(tmp_path, H1, "RSN6-ELC.AT2", ("Array #9, 180", f"Array #9, {word}", 1))
    assert read_at2(path).provenance["component"]["kind"] == "horizontal"
    assert error_of(read_components, [H1, H2, path]).startswith(f"{path}:2: holds a horizontal component")


def test_a_file_name_ending_in_channel_and_location_names_a_vertical(tmp_path: Path) -> None:
    path = variant(tmp_path, H1, "NGA_East_0001_ST01.BHZ.00.AT2", ("Array #9, 180", "Array #9, BHZ00", 1))
    assert read_at2(path).provenance["component"]["kind"] == "vertical"
    unnamed = variant(tmp_path, H1, "ST02.BHZ.00.AT2", ("Array #9, 180", "Array #9, X", 1))
    entry = read_at2(unnamed).provenance["component"]
    assert entry == {"kind": "vertical", "line": None, "said_by": "the file name 'ST02.BHZ.00.AT2', SEED channel "
                     "BHZ location 00: orientation Z, vertical"}
    contradicted = variant(tmp_path, H1, "ST03.BHZ.00.AT2", ("Array #9, 180", "Array #9, HN1", 1))
    assert error_of(read_at2, contradicted) == (
        f"{contradicted}:2: line 2 gives the horizontal component 'HN1' but the file name 'ST03.BHZ.00.AT2' names a "
        "vertical one; expected the two to agree (rename the file or fix line 2)"
    )


@pytest.mark.parametrize("word", ["HNA", "HNU", "X", "BHZ0"])
def test_an_unknown_peer_component_is_read_with_a_warning(tmp_path: Path, word: str) -> None:
    path = variant(tmp_path, H1, "RSN6-ELC.AT2", ("Array #9, 180", f"Array #9, {word}", 1))
    with pytest.warns(RecordWarning) as caught:
        motion = read_at2(path)
    assert len(caught) == 1
    assert str(caught[0].message).startswith(
        f"{path}:2: the component (horizontal or vertical) is unknown: line 2 gives {word!r}, not a component and "
        "the file name does not say; it is played as a horizontal one"
    )
    assert motion.provenance["component"]["kind"] == "unknown"


def test_a_plain_text_file_named_by_its_seed_channel_is_read_as_that_component(tmp_path: Path) -> None:
    vertical = tmp_path / "CI.PAS.00.HNZ.txt"
    vertical.write_bytes(TEXT.read_bytes())
    assert load_record(str(vertical), accept_vertical=True).provenance["component"]["kind"] == "vertical"
    assert error_of(read_components, [vertical, H2]).startswith(
        f"{vertical}: horizontal component 1 is named like a vertical one (the file name 'CI.PAS.00.HNZ.txt', SEED "
        "channel HNZ location 00"
    )
    north = tmp_path / "CI.PAS.00.HNN.txt"
    north.write_bytes(TEXT.read_bytes())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_record(str(north)).provenance["component"]["kind"] == "horizontal"


def test_a_plain_text_file_that_names_no_component_is_read_with_a_warning() -> None:
    with pytest.warns(RecordWarning) as caught:
        motion = load_record(str(TEXT))
    assert [str(w.message) for w in caught] == [
        f"{TEXT}: the component (horizontal or vertical) is unknown: a plain text file names no component and the "
        "file name does not say; it is played as a horizontal one, check it before playing it"
    ]
    assert motion.provenance["component"]["kind"] == "unknown"


def test_csv_columns_named_by_seed_channels_are_the_components(tmp_path: Path) -> None:
    path = variant(tmp_path, CSV3, "seed.csv", ("time_s,acc_h_g,acc_h2_g,acc_v_g", "time_s,HN2_g,HNZ.00 [g],HN1_g", 1))
    named = load_record(str(CSV3))
    seed = load_record(str(path))
    np.testing.assert_array_equal(seed.acc_h, named.acc_h)  # HN2: the first horizontal in column order
    np.testing.assert_array_equal(seed.acc_v, named.acc_h2)  # HNZ.00: the vertical
    np.testing.assert_array_equal(seed.acc_h2, named.acc_v)  # HN1: the second horizontal
    odd = variant(tmp_path, CSV3, "odd.csv", ("time_s,acc_h_g,acc_h2_g,acc_v_g", "time_s,HNA_g,acc_h2_g,acc_v_g", 1))
    assert error_of(load_record, str(odd)) == (
        f"{odd}:1: column 2, 'HNA_g', is SEED channel HNA: orientation A, not a horizontal or vertical orientation; "
        "expected a horizontal (N, E, 1, 2) or vertical (Z, 3) channel"
    )


def test_a_one_column_csv_says_its_component_by_column_or_file_name(tmp_path: Path) -> None:
    rows = "time_s,{}\n0.00,0.1\n0.01,-0.2\n0.02,0.05\n"
    seed = tmp_path / "seed.csv"
    seed.write_text(rows.format("HNE_g"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        entry = load_record(str(seed)).provenance["component"]
    assert entry == {"kind": "horizontal", "line": 1,
                     "said_by": "CSV column 'HNE_g', SEED channel HNE: orientation E, east"}
    bare = tmp_path / "bare.csv"
    bare.write_text(rows.format("acc_g"))
    unknown = r"bare.csv: the component \(horizontal or vertical\) is unknown: the CSV column names no component"
    with pytest.warns(RecordWarning, match=unknown + r" \(a bare 'acc'\) and the file name does not say"):
        load_record(str(bare))
    named = tmp_path / "ST01.HNZ.csv"
    named.write_text(rows.format("acc_g"))
    assert "holds a vertical component (the file name 'ST01.HNZ.csv'" in error_of(load_record, str(named))
    clash = tmp_path / "ST02.HNZ.csv"
    clash.write_text(rows.format("acc_h_g"))
    assert error_of(load_record, str(clash)).startswith(
        f"{clash}:1: CSV column 'acc_h_g' is a horizontal channel but the file name 'ST02.HNZ.csv', SEED channel HNZ: "
        "orientation Z, vertical says vertical"
    )


def test_an_h5_record_of_an_unknown_component_warns_at_every_read(tmp_path: Path) -> None:
    from rig.records import read_h5, write_record

    with pytest.warns(RecordWarning):
        motion = load_record(str(TEXT))
    path = write_record(motion, tmp_path / "elc.h5")
    with pytest.warns(RecordWarning, match=r"elc.h5: the component \(horizontal or vertical\) is unknown: its source "
                                           r"file did not say"):
        read_h5(path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert read_h5(write_record(read_at2(H1), tmp_path / "h1.h5")).provenance["component"]["kind"] == "horizontal"


def test_a_cosmos_channel_of_unknown_orientation_takes_its_seed_file_name(tmp_path: Path) -> None:
    vertical = variant(tmp_path, SINE, "NP.7010.00.HNZ.V2", ("     360", "    2000", 1))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        entry = read_cosmos(vertical).provenance["component"]
    assert entry["kind"] == "vertical" and entry["said_by"].startswith("the file name 'NP.7010.00.HNZ.V2'")
    clash = variant(tmp_path, SINE, "NP.7010.00.HNZ.V2C", ("     360", "      90", 1))
    assert error_of(read_cosmos, clash) == (
        f"{clash}:20: the COSMOS orientation code 90: 90 deg, chan 1 is horizontal but the file name "
        "'NP.7010.00.HNZ.V2C', SEED channel HNZ location 00: orientation Z, vertical says vertical; expected the two "
        "to agree (rename the file)"
    )
