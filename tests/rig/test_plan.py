"""``rig plan`` through the real command line: the expected overturns of a sequence's bodies on the drives the table
will play, checked against the reference solver (DOP853 with exact events, not the fast engine the plan uses), the
mirror symmetry of a record played in both polarities on a level plate, and the exact power of the equivalence
test at the overturns it asks for."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from typer.testing import CliRunner

from analysis import simulate
from analysis.agreement import equivalence_power
from analysis.body import G
from rig.cli import app
from rig.sequence import load_sequence

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
runner = CliRunner()


def plan_json(*args: str) -> dict:
    out = runner.invoke(app, ["plan", *args, "--json"])
    assert out.exit_code == 0, out.output
    return json.loads(out.stdout)


@pytest.mark.slow
def test_the_quick_sequence_s_expected_overturns_are_the_reference_solver_s() -> None:
    """(About a minute on two busy cores: the reference solver on twelve scenes.)"""
    plan = plan_json(str(EXAMPLES / "quick.toml"))
    seq = load_sequence(EXAMPLES / "quick.toml")
    assert plan["records"] == 3 and plan["repetitions"] == 1 and plan["margin"] == 0.05 and plan["power"] == 0.8
    rows = {(r["angle_deg"], r["body_id"]): r for r in plan["bodies"]}
    assert len(rows) == 2 * 2
    for run in seq.plan():
        drive = seq.prepare(run)
        acc_h, acc_v = drive.accelerations[:, 0] / G, drive.accelerations[:, 2] / G
        for placed in seq.bodies:
            rows[(run.angle_deg, placed.body_id)].setdefault("reference", []).append(
                simulate(placed.body, acc_h, 1.0 / drive.rate, beta=run.angle, acc_v=acc_v, solver="reference",
                         restitution=0.0).direction)
    for row in rows.values():
        directions = row["reference"]
        assert row["runs"] == 3
        assert row["overturned"] == sum(1 for d in directions if d)
        assert row["towards_low"] == sum(1 for d in directions if d == 1)
        if row["overturned"]:
            n = row["overturns_needed"]
            cor = row["towards_low"] / row["overturned"]
            assert row["cor"] == pytest.approx(cor)
            assert equivalence_power(cor, n, cor, n, 0.05) >= 0.8 > equivalence_power(cor, n - 1, cor, n - 1, 0.05)
            assert row["runs_needed"] == math.ceil(n * 3 / row["overturned"])
            assert row["repetitions_needed"] == math.ceil(row["runs_needed"] / 3)
    assert any(row["overturned"] for row in rows.values())  # the quick records do overturn the bodies


def test_both_polarities_on_the_level_plate_give_a_coin_toss(tmp_path: Path) -> None:
    """A record and its mirror image on a level plate: every overturn of a symmetric block one way is matched by
    one the other way, so the expected COR is exactly 50 %; a wider margin needs fewer overturns (∝ 1/δ²). (Table V's
    body 5 has its centre of gravity 0.5 mm off the middle: it is centred here, b_cg = b/2.)"""
    text = (EXAMPLES / "quick.toml").read_text().replace("angles_deg = [0, 4]", 'angles_deg = [0]\npolarity = "both"')
    text = text.replace("table5 = 5 ", "b_cg = 0.0245\ntable5 = 5 ")
    text = text.replace('config = "rig-table4.toml"', f'config = "{EXAMPLES / "rig-table4.toml"}"')
    (tmp_path / "both.toml").write_text(text)
    five = plan_json(str(tmp_path / "both.toml"))
    ten = plan_json(str(tmp_path / "both.toml"), "--margin", "10")
    assert five["records"] == 6
    for row in five["bodies"]:
        assert row["runs"] == 6 and row["towards_low"] * 2 == row["overturned"]
    overturning = [row for row in five["bodies"] if row["overturned"]]
    assert overturning and all(row["cor"] == 0.5 for row in overturning)
    n5, n10 = overturning[0]["overturns_needed"], ten["bodies"][0]["overturns_needed"]
    assert n5 / n10 == pytest.approx(4.0, rel=0.05)


def test_plan_refuses_bad_options_and_files(tmp_path: Path) -> None:
    bad = runner.invoke(app, ["plan", str(EXAMPLES / "quick.toml"), "--margin", "0"])
    assert bad.exit_code == 2 and "--margin" in bad.stderr
    bad = runner.invoke(app, ["plan", str(EXAMPLES / "quick.toml"), "--power", "1.5"])
    assert bad.exit_code == 2 and "--power" in bad.stderr
    (tmp_path / "bad.toml").write_text('angles_deg = [0]\npolarity = "sideways"\nrecords = ["fema:KOBE/NIS000"]\n'
                                       "[[bodies]]\ntable5 = 4\nx = 0.0\ny = 0.0\n")
    bad = runner.invoke(app, ["plan", str(tmp_path / "bad.toml")])
    assert bad.exit_code == 2 and "bad.toml:2: polarity: expected one of" in bad.stderr
