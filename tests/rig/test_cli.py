"""The ``rig`` command line: JSON contracts of docs/architecture.md §7 and clear errors (exit 2)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from typer.testing import CliRunner

from analysis import Body, simulate
from rig.cli import app
from rig.records import load_record

runner = CliRunner()
RECORD = "fema-farfield:NORTHR/MUL009"


def run_json(*args: str) -> dict:
    result = runner.invoke(app, [*args, "--json"])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def test_simulate_json_carries_the_contract_fields_and_the_api_result() -> None:
    out = run_json("simulate", RECORD, "--body", "0.10x0.50", "--angle", "5")
    assert {"direction", "t_overturn", "theta_max", "status"} <= out.keys()
    rec = load_record(RECORD)
    direct = simulate(Body(0.10, 0.50), rec.acc_h, rec.dt, beta=math.radians(5))
    assert out["direction"] == direct.direction
    assert out["t_overturn"] == pytest.approx(direct.t_overturn)
    assert out["direction"] == 1 and out["status"] == "overturned"


def test_simulate_reference_and_general_options() -> None:
    ref = run_json("simulate", RECORD, "--body", "0.10x0.50", "--angle", "5", "--solver", "reference")
    fast = run_json("simulate", RECORD, "--body", "0.10x0.50", "--angle", "5")
    assert ref["solver"] == "reference" and ref["direction"] == fast["direction"]
    assert ref["t_overturn"] == pytest.approx(fast["t_overturn"], abs=1e-4)
    neg = run_json("simulate", RECORD, "--body", "0.10x0.50", "--angle", "0", "--sign", "-1")
    pos = run_json("simulate", RECORD, "--body", "0.10x0.50", "--angle", "0")
    assert neg["direction"] == -pos["direction"]  # level plate: negating the record mirrors the outcome


def test_study_json_counts_and_cor_table() -> None:
    out = run_json("study", "--records", "fema-farfield", "--bodies", "table1:1,4", "--angles", "0,5")
    assert out["scenes"] == 2 * 44 * 2 * 2
    assert len(out["cor"]) == 4
    for row in out["cor"]:
        assert row["desired"] <= row["overturned"] <= row["scenes"] == 88
        if row["angle_deg"] == 0 and row["overturned"]:
            assert row["cor"] == pytest.approx(0.5)  # both signs on a level plate mirror each other
    assert {"gcor", "scor", "seconds"} <= out.keys()


def test_design_from_a_saved_study(tmp_path: Path) -> None:
    study_file = tmp_path / "study.json"
    result = runner.invoke(app, ["study", "--records", "fema", "--bodies", "table1", "--angles", "0:7:0.5", "--json"])
    assert result.exit_code == 0, result.output
    study_file.write_text(result.stdout)
    fitted = run_json("design", "--body", "0.10x0.50", "--confidence", "0.95", "--equation", "GCOR",
                      "--study", str(study_file))
    c1, c2 = json.loads(result.stdout)["gcor"]["c1"], json.loads(result.stdout)["gcor"]["c2"]
    assert fitted["source"] == "fitted"
    assert math.tanh(fitted["angle_rad"] / c1) * c2 + 0.5 == pytest.approx(0.95)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["simulate", "fema-farfield:NOPE", "--body", "0.1x0.5"], "NOPE"),
        (["simulate", "nosuite:X", "--body", "0.1x0.5"], "nosuite"),
        (["simulate", RECORD, "--body", "0.1x0.5", "--angle", "15"], "cannot stand"),
        (["simulate", RECORD, "--body", "0.1by0.5"], "BxH"),
        (["simulate", RECORD, "--body", "0.1x0.5", "--model", "sliding"], "model"),
        (["study", "--records", "fema-farfield", "--angles", "0:7:0"], "STEP > 0"),
        (["study", "--records", "fema-farfield", "--bodies", "table1:13"], "table1"),
    ],
)
def test_bad_input_exits_2_and_says_what_is_wrong(args: list[str], message: str) -> None:
    result = runner.invoke(app, args)
    assert result.exit_code == 2
    assert message in result.output
    assert "Traceback" not in result.output


def test_a_study_in_which_nothing_overturns_is_summarised_not_refused() -> None:
    """A large stocky body on one weak record: no overturn, no COR to fit — the summary says so, exit 0."""
    result = runner.invoke(app, ["study", "--records", "fema-farfield:NORTHR/MUL009", "--bodies", "0.38x1.5",
                                 "--angles", "0", "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert out["cor"][0]["overturned"] == 0 and out["gcor_paper"]["eq12_error"] is None
    assert "error" in out["gcor"]
