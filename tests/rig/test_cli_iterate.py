"""``rig iterate`` end to end on the emulated table (``--dynamics servo``, MAVLink on loopback): the identification
and iterations are runs of the session with their errors, ``/compensation`` holds the response and the iterations,
the drive file plays; ``rig report`` shows them. The command in this process (``tests.helpers.cli.rig``); its
refusals of bad input before the table is contacted in the fast tier."""

from __future__ import annotations

import json

import h5py
import pytest

from rig.drive.file import load_drive
from tests.helpers.cli import rig

ITERATE = ["fema:KOBE/NIS000", "--angle", "4", "--emulate", "--window", "5,10", "--corner", "1",
           "--identify-seconds", "10", "--iterations", "1"]


@pytest.mark.integration  # starts the emulator's process
@pytest.mark.slow
def test_iterate_on_the_emulator(tmp_path):
    session = tmp_path / "s.h5"
    done = rig("iterate", *ITERATE, "-o", str(session), "--json")
    assert done.exit_code == 0, done.stderr
    out = json.loads(done.stdout)
    assert set(out) >= {"iterations", "converged", "drive"} and out["law"] == "mimo"
    errors = [it["rms_error_pct"] for it in out["iterations"]]
    assert len(errors) == 3 and errors[0] > 10.0 and errors[-1] < errors[0]
    assert [it["level_db"] for it in out["iterations"]] == [-12.0, -6.0, 0.0]
    for it in out["iterations"]:
        assert it["peak_error_pct"] >= 0 and 0 < it["fall_line"]["trac"] <= 1 and it["psa_error_max_pct"] >= 0
        assert set(it["axes"]) == {"surge", "lateral", "heave"} and it["peak_to_limit"] <= 1.0
    with h5py.File(session, "r") as h5:
        runs = sorted(h5["runs"])
        assert len(runs) == 4 and h5["runs"][runs[0]].attrs["compensation"] == "identify"
        for name, err in zip(runs[1:], errors, strict=True):
            assert h5["runs"][name].attrs["rms_error_pct"] == pytest.approx(err, rel=1e-6)
        group = h5["compensation"]
        assert group["iterations"].shape == (3,) and group["achieved"].shape[0] == 3
        assert group["response"]["surge_coherence"].max() > 0.9 and group["response_matrix"].shape[1:] == (3, 3)
        assert list(group["iterations"]["level_db"]) == [-12.0, -6.0, 0.0]
    drive = load_drive(out["drive"])
    assert drive.angle == pytest.approx(0.0698, abs=1e-4)
    report = rig("report", str(session), "-o", str(tmp_path / "s.html"), "--json")
    assert report.exit_code == 0, report.stderr
    html = (tmp_path / "s.html").read_text()
    assert "Drive compensation" in html and "coherence" in html and "TRAC" in html


@pytest.mark.integration  # starts the emulator's process
@pytest.mark.slow
def test_a_first_level_whose_predicted_response_leaves_the_table_is_refused_with_the_level_that_fits(tmp_path):
    """The coupled plate amplifies this excerpt about twice near its surge mode: at -6 dB the prediction passes
    0.6 g, so nothing is played and the error names the breach and the ramp that fits, which then plays."""
    session = tmp_path / "s.h5"
    done = rig("iterate", *ITERATE, "--levels", "-6,0", "-o", str(session))
    assert done.exit_code == 3, done.stderr
    assert "as prepared at -6 dB not played" in done.stderr and "(0.600 g)" in done.stderr
    assert "hint: run it again with --levels=-12,-6,0 and a new -o file" in done.stderr
    with h5py.File(session, "r") as h5:
        assert [h5["runs"][name].attrs["compensation"] for name in h5["runs"]] == ["identify"]


def test_iterate_refuses_bad_input(tmp_path):
    done = rig("iterate", "fema:KOBE/NIS000", "--angle", "4", cwd=tmp_path)
    assert done.exit_code == 2 and "either --table URL or --emulate" in done.stderr
    done = rig("iterate", "fema:NO/SUCH", "--angle", "4", "--emulate", cwd=tmp_path)
    assert done.exit_code == 2 and "NO/SUCH" in done.stderr
    for option, value in (("--law", "lms"), ("--levels", "-6,-12"), ("--levels", "-12,-6"), ("--speed", "fast"),
                          ("--headroom", "70%")):
        done = rig("iterate", "fema:KOBE/NIS000", "--emulate", option, value, cwd=tmp_path)
        assert done.exit_code == 2 and option.lstrip("-") in done.stderr, (option, done.stderr)
    assert not list(tmp_path.iterdir())
