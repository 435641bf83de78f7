"""The user record library (import, list, show, ``library:NAME``) and ``rig records …`` on it.

Every test uses a library under tmp_path (``RIG_RECORD_LIBRARY`` set by the autouse fixture, or
``--library``): the real user data directory is never touched.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from rig.records import (
    RecordError,
    default_library_dir,
    h5record,
    import_records,
    library_dir,
    library_names,
    load_library_record,
    load_record,
    load_records,
    read_at2,
    read_h5,
)

DATA = Path(__file__).parents[1] / "data" / "records"
ELC180 = DATA / "RSN6_IMPVALL.I_I-ELC180.AT2"
ELC270 = DATA / "RSN6_IMPVALL.I_I-ELC270.AT2"
ELC_UP = DATA / "RSN6_IMPVALL.I_I-ELC-UP.AT2"
TRIPLE = f"{ELC180}+{ELC270}+{ELC_UP}"


@pytest.fixture(autouse=True)
def library(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A fresh library directory (not created yet) named by RIG_RECORD_LIBRARY."""
    root = tmp_path / "library"
    monkeypatch.setenv("RIG_RECORD_LIBRARY", str(root))
    return root


@pytest.fixture
def sources(tmp_path: Path) -> Path:
    """Copies of the test records (so that checks on the source files cannot touch the repository)."""
    root = tmp_path / "sources"
    shutil.copytree(DATA, root)
    return root


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def error_of(call: object, *args: object, **kwargs: object) -> str:
    with pytest.raises(RecordError) as info:
        call(*args, **kwargs)  # type: ignore[operator]
    return str(info.value)


# --------------------------------------------------------------------------------------------------
# Where the library is
# --------------------------------------------------------------------------------------------------


def test_library_dir_precedence(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, library: Path) -> None:
    assert library_dir() == library
    assert library_dir(tmp_path / "explicit") == tmp_path / "explicit"
    monkeypatch.delenv("RIG_RECORD_LIBRARY")
    monkeypatch.setattr("sys.platform", "linux")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    assert library_dir() == default_library_dir() == tmp_path / "xdg" / "shaketable-rig" / "records"
    monkeypatch.setenv("XDG_DATA_HOME", "relative/ignored")
    assert default_library_dir() == tmp_path / "home" / ".local" / "share" / "shaketable-rig" / "records"
    monkeypatch.delenv("XDG_DATA_HOME")
    assert default_library_dir() == tmp_path / "home" / ".local" / "share" / "shaketable-rig" / "records"
    monkeypatch.setattr("sys.platform", "darwin")
    assert default_library_dir() == (
        tmp_path / "home" / "Library" / "Application Support" / "shaketable-rig" / "records"
    )
    monkeypatch.setattr("sys.platform", "win32")
    monkeypatch.setenv("LOCALAPPDATA", str(tmp_path / "local"))
    assert default_library_dir() == tmp_path / "local" / "shaketable-rig" / "records"
    monkeypatch.delenv("LOCALAPPDATA")
    assert default_library_dir() == tmp_path / "home" / "AppData" / "Local" / "shaketable-rig" / "records"


# --------------------------------------------------------------------------------------------------
# Import and load
# --------------------------------------------------------------------------------------------------


def test_import_list_and_load(library: Path, sources: Path) -> None:
    at2 = sources / "RSN6_IMPVALL.I_I-ELC180.AT2"
    before = (sha(at2), at2.stat().st_mtime_ns)
    (entry,) = import_records([str(at2)])
    assert (sha(at2), at2.stat().st_mtime_ns) == before  # the source is never modified
    assert entry.name == "RSN6_IMPVALL.I_I-ELC180" and not entry.replaced
    assert entry.path == library / "RSN6_IMPVALL.I_I-ELC180.h5"
    assert sorted(p.name for p in library.iterdir()) == ["RSN6_IMPVALL.I_I-ELC180.h5"]
    assert library_names() == ["RSN6_IMPVALL.I_I-ELC180"]

    loaded = load_record("library:RSN6_IMPVALL.I_I-ELC180")
    original = read_at2(at2)
    assert loaded.acc_h.tobytes() == original.acc_h.tobytes() and loaded.dt == original.dt
    p = loaded.provenance
    assert p["path"] == str(at2.resolve()) and p["source_sha256"] == before[0]  # the original file
    assert p["format"] == "PEER NGA-West2 AT2" and "imported" in p
    assert p["stored_in"]["path"] == str(entry.path.resolve())
    assert [m.name for m in load_records("library")] == ["RSN6_IMPVALL.I_I-ELC180"]


def test_import_bidirectional_with_a_name_that_needs_encoding(library: Path, sources: Path) -> None:
    spec = "+".join(str(sources / n) for n in (ELC180.name, ELC270.name, ELC_UP.name))
    (entry,) = import_records([spec], name="IMPVALL/ELC 1940 (3-comp)")
    assert entry.path.name == "IMPVALL%2FELC 1940 %283-comp%29.h5"
    gm = load_library_record("IMPVALL/ELC 1940 (3-comp)")
    assert gm.name == "IMPVALL/ELC 1940 (3-comp)"
    assert gm.acc_h2 is not None and gm.acc_v is not None
    assert gm.acc_v.tobytes() == read_at2(ELC_UP).acc_h.tobytes()
    files = gm.provenance["files"]
    assert [Path(f).name for f in files] == [ELC180.name, ELC270.name, ELC_UP.name]


def test_import_text_with_dt_and_units(sources: Path) -> None:
    bare = sources / "bare.txt"
    bare.write_text("0.981\n-1.962\n")
    with pytest.raises(RecordError, match="no time step"):
        import_records([str(bare)], units="m/s/s")
    (entry,) = import_records([str(bare)], dt=0.02, units="m/s/s")
    gm = load_library_record(entry.name)
    np.testing.assert_allclose(gm.acc_h, [0.1, -0.2], rtol=1e-15)
    assert gm.dt == 0.02 and gm.provenance["units_from"] == "given"


def test_duplicate_refused_then_replaced(library: Path, sources: Path) -> None:
    import_records([str(sources / ELC180.name)], name="elc")
    stored = (library / "elc.h5").read_bytes()
    assert error_of(import_records, [str(sources / ELC270.name)], name="elc") == (
        f"the library {library} already has a record 'elc' (elc.h5); expected a new name (--name) or "
        "--replace to replace it"
    )
    assert (library / "elc.h5").read_bytes() == stored
    (entry,) = import_records([str(sources / ELC270.name)], name="elc", replace=True)
    assert entry.replaced
    assert load_library_record("elc").acc_h.tobytes() == read_at2(ELC270).acc_h.tobytes()
    assert sorted(p.name for p in library.iterdir()) == ["elc.h5"]


def test_batch_import_checks_everything_before_writing(library: Path, sources: Path) -> None:
    bad = sources / "bad.AT2"
    bad.write_text("PEER NGA STRONG MOTION DATABASE RECORD\n")
    with pytest.raises(RecordError, match="4-line PEER header"):
        import_records([str(sources / ELC180.name), str(bad)])
    assert not library.exists()
    message = error_of(import_records, [str(sources / ELC180.name), str(sources / ELC180.name)])
    assert message == "two of the records to import are named 'RSN6_IMPVALL.I_I-ELC180'; expected distinct names"
    assert error_of(import_records, [str(ELC180), str(ELC270)], name="x") == (
        "a name was given for 2 records; expected one record with a name"
    )
    assert not library.exists()


@pytest.mark.parametrize("name", ["", " padded", "tab\there", "x" * 121])
def test_bad_names_refused(name: str) -> None:
    with pytest.raises(RecordError, match="cannot name a library record"):
        import_records([str(ELC180)], name=name)


def test_failed_write_leaves_no_partial_file_and_keeps_the_old_record(
    library: Path, sources: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import_records([str(sources / ELC180.name)], name="elc")
    old = (library / "elc.h5").read_bytes()
    real = h5record._write_contents
    seen: list[Path] = []

    def fail_midway(h5: object, motion: object, provenance: str) -> None:
        real(h5, motion, provenance)  # the temporary file now holds data ...
        seen.extend(p for p in library.iterdir() if p.name.endswith(".tmp"))
        raise OSError(28, "No space left on device")  # ... and the disk is full

    monkeypatch.setattr(h5record, "_write_contents", fail_midway)
    for replace in (True, False):
        name = "elc" if replace else "new"
        message = error_of(import_records, [str(sources / ELC270.name)], name=name, replace=replace)
        assert message == f"{library / (name + '.h5')}: cannot write (No space left on device)"
    assert len(seen) == 2  # a temporary file existed during each write
    assert sorted(p.name for p in library.iterdir()) == ["elc.h5"]
    assert (library / "elc.h5").read_bytes() == old
    assert read_h5(library / "elc.h5").acc_h.tobytes() == read_at2(ELC180).acc_h.tobytes()


def test_library_errors(library: Path) -> None:
    assert library_names() == [] and load_records("library") == []
    assert error_of(load_record, "library:nope") == (
        f"no record 'nope' in the library {library}. List them with `rig records list library`."
    )
    import_records([str(ELC180)], name="elcentro")
    assert error_of(load_record, "library:elcentr") == (
        f"no record 'elcentr' in the library {library}. Did you mean: elcentro? "
        "List them with `rig records list library`."
    )
    assert error_of(load_record, "library") == (
        "'library' is the record library (1 records), not one record; use library:NAME "
        "(names: `rig records list library`)"
    )
    assert "has its own dt and units" in error_of(load_record, "library:elcentro", units="g")


# --------------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------------



def run(app: typer.Typer, *args: str) -> dict:
    result = CliRunner().invoke(app, ["records", *args])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def test_cli_import_list_show(app: typer.Typer, library: Path, sources: Path) -> None:
    spec = "+".join(str(sources / n) for n in (ELC180.name, ELC270.name, ELC_UP.name))
    data = run(app, "import", spec, str(sources / "MUL009.AT2"), "--json")
    assert data["library"] == str(library) and data["count"] == 2
    triple, mul = data["imported"]
    assert triple["name"] == "RSN6_IMPVALL.I_I-ELC180+RSN6_IMPVALL.I_I-ELC270+RSN6_IMPVALL.I_I-ELC-UP"
    assert (triple["npts"], triple["dt"], triple["pga"], triple["pga_h2"], triple["pga_v"]) == (
        12, 0.01, 0.313, 0.215, 0.18
    )
    assert triple["source"] == spec and not triple["replaced"]
    assert Path(mul["path"]) == library / "MUL009.h5" and mul["pga"] == 0.416

    overview = run(app, "list", "--json")
    entry = next(s for s in overview["suites"] if s["name"] == "library")
    assert entry == {"name": "library", "components": 2, "path": str(library)}
    assert overview["total_components"] == 102

    listing = run(app, "list", "library", "--json")
    assert listing["count"] == 2 and [c["name"] for c in listing["components"]] == [
        "MUL009", "RSN6_IMPVALL.I_I-ELC180+RSN6_IMPVALL.I_I-ELC270+RSN6_IMPVALL.I_I-ELC-UP"
    ]

    shown = run(app, "show", "library:MUL009", "--json")
    assert shown["npts"] == 10 and shown["provenance"]["format"] == "PEER NGA AT2"
    assert shown["provenance"]["source_sha256"] == sha(sources / "MUL009.AT2")

    human = CliRunner().invoke(app, ["records", "list", "library"])
    assert human.exit_code == 0 and "PGA v [g]" in human.stdout and "MUL009" in human.stdout


def test_cli_library_option_and_replace(app: typer.Typer, tmp_path: Path, library: Path) -> None:
    other = tmp_path / "other-library"
    run(app, "import", str(ELC180), "--name", "elc", "--library", str(other), "--json")
    assert not library.exists() and (other / "elc.h5").is_file()
    result = CliRunner().invoke(app, ["records", "import", str(ELC270), "--name", "elc", "--library", str(other)])
    assert result.exit_code == 2 and result.stdout == ""
    assert result.stderr == (
        f"error: the library {other} already has a record 'elc' (elc.h5); expected a new name (--name) or "
        "--replace to replace it\n"
    )
    data = run(app, "import", str(ELC270), "--name", "elc", "--library", str(other), "--replace", "--json")
    assert data["imported"][0]["replaced"] is True
    assert run(app, "show", "library:elc", "--library", str(other), "--json")["pga"] == 0.215
    human = CliRunner().invoke(app, ["records", "import", str(ELC180), "--name", "elc2", "--library", str(other)])
    assert human.exit_code == 0 and "elc2" in human.stdout


def test_cli_show_file_with_dt_and_units(app: typer.Typer, tmp_path: Path) -> None:
    bare = tmp_path / "bare.acc"
    bare.write_text("98.1\n-49.05\n")
    data = run(app, "show", str(bare), "--dt", "0.005", "--units", "gal", "--json")
    assert (data["dt"], data["npts"]) == (0.005, 2)
    assert data["pga"] == pytest.approx(0.1, rel=1e-15)


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["show", "{bad}", "--json"], "error: {bad}:4: expected 'NPTS= <n>, DT= <dt> SEC' (NGA-West2)"),
        (["import", "{bad}", "--json"], "error: {bad}:4: expected 'NPTS= <n>, DT= <dt> SEC' (NGA-West2)"),
        (["show", "{bare}", "--units", "g"], "error: {bare}: no time step: a one-column file needs"),
        (["show", "{bare}", "--dt", "-1", "--units", "g"],
         "error: the given dt must be a number of seconds from 1e-05 to 1"),
        (["show", "library:missing"], "error: no record 'missing' in the library"),
    ],
)
def test_cli_errors_exit_2_on_stderr(app: typer.Typer, tmp_path: Path, args: list[str], expected: str) -> None:
    bad = tmp_path / "bad.AT2"
    bad.write_text(ELC180.read_text().replace("NPTS=     12, DT=   .0100 SEC,", "NPTS= twelve"))
    bare = tmp_path / "bare.txt"
    bare.write_text("0.1\n")
    paths = {"bad": str(bad), "bare": str(bare)}
    result = CliRunner().invoke(app, ["records", *(a.format(**paths) for a in args)])
    assert result.exit_code == 2
    assert result.stdout == ""
    assert result.stderr.startswith(expected.format(**paths))
    assert "Traceback" not in result.output
    assert sorted(os.listdir(tmp_path)) == ["bad.AT2", "bare.txt"]  # nothing imported
