"""The report's sequence section takes a stored sequence's records in both of the sequence file's forms: a table
of keys (``{ record = "…", window_s = […] }``) or just the record's name."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from rig.cli import app
from rig.session import SessionLog


def test_records_given_by_name_or_as_tables_are_both_listed(tmp_path: Path) -> None:
    path = tmp_path / "session.h5"
    sequence = {"name": "both forms", "angles_deg": [0.0], "repetitions": 1,
                "records": ["suite:by-name", {"record": "suite:as-table", "window_s": [1.0, 4.0]}]}
    SessionLog.create(path, {"table": {}}, sequence, "0.1.0+test").close()
    report = tmp_path / "report.html"
    result = CliRunner().invoke(app, ["report", str(path), "-o", str(report)])
    assert result.exit_code == 0, result.output
    html = report.read_text()
    assert "suite:by-name" in html and "suite:as-table" in html and "1–4" in html
