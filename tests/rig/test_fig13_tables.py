"""The Fig. 13 tables `rig analyze` and `rig demo` print fit 100 columns (issue 40, item 7): every cell on one line
in a terminal of that width, the long verdicts as footnotes below the table."""

from __future__ import annotations

import dataclasses
import io

import pytest
from rich.console import Console
from rich.table import Table

from rig.analyze.fig13 import Fig13Row, rule_label
from rig.analyze.results import SessionAnalysis
from rig.cli.analyze import WIDTH, fig13_tables, rules_tables


def wide_row(model: str = "general", body_id: int = 12) -> Fig13Row:
    """A row with the widest numbers a campaign gives: three-digit counts, rates at 100 %, a difference of
    −100 points, a verdict with the longest words."""
    return Fig13Row(angle_deg=10.5, body_id=body_id, model=model, runs=120, records=100, overturned_analysis=120,
                    towards_low_analysis=120, cor_analysis=1.0, overturned_experiment=115, towards_low_experiment=0,
                    cor_experiment=0.0, difference=-1.0, cor_analysis_low=0.97, cor_analysis_high=1.0,
                    cor_experiment_low=0.0, cor_experiment_high=0.03, difference_low=-1.0, difference_high=-0.95,
                    verdict="not resolved", p_equivalent=0.5, p_different=0.5, runs_to_resolve=4100, margin=0.05,
                    both_overturned=115, low_high=115, high_low=110, p_direction=0.05, analysis_only=115,
                    experiment_only=110, p_overturn=0.05)


def analysis(rows: list[Fig13Row], restitution: str = "0.0") -> SessionAnalysis:
    return SessionAnalysis(path="session.h5", models=tuple(dict.fromkeys(r.model for r in rows)), solver="fast",
                           restitution=restitution, fitted_restitution={}, runs=[], skipped=[], margin=0.05,
                           fig13=rows, max_difference={}, agreement={}, written=False)


def natural_width(table: Table) -> int:
    """The columns the table takes when nothing wraps (its caption wraps to the table, as prose)."""
    return Console(width=1000).measure(table).maximum


def printed(parts: list) -> str:
    """What a terminal of `WIDTH` columns shows."""
    console = Console(width=WIDTH, file=io.StringIO())
    for part in parts:
        console.print(part)
    return console.file.getvalue()


def test_the_comparison_fits_100_columns_with_the_long_verdicts_as_footnotes() -> None:
    different = dataclasses.replace(wide_row(), verdict="different")
    parts = fig13_tables(analysis([wide_row(), wide_row(body_id=0), different]))
    tables = [part for part in parts if isinstance(part, Table)]
    assert len(tables) == 2
    assert [natural_width(table) for table in tables] <= [WIDTH] * 2, [natural_width(t) for t in tables]
    text = printed(parts)
    assert "not resolved [1]" in text and "not resolved [2]" in text and "different" in text
    assert "[1] general, 10.5°, body 12: not resolved with 120 runs (about 4100 would)" in text
    assert "[2] general, 10.5°, average: not resolved with 120 body-runs (about 4100 would)" in text
    assert "115/110 p=0.05" in text and "100 [97–100]" in text and "-100 [-100, -95]" in text
    assert max(len(line) for line in text.splitlines()) <= WIDTH


@pytest.mark.parametrize("rules", [("plastic",), ("plastic", "housner", "fit")])
def test_the_rules_side_by_side_fit_100_columns(rules: tuple[str, ...]) -> None:
    rows = [dataclasses.replace(wide_row(), model=rule_label("general", rule)) for rule in rules]
    parts = rules_tables(analysis(rows, restitution="all"))
    tables = [part for part in parts if isinstance(part, Table)]
    assert len(tables) == 1 and natural_width(tables[0]) <= WIDTH
    text = printed(parts)
    names = {"plastic": "plastic", "housner": "Housner's", "fit": "fitted"}
    for number, rule in enumerate(rules, start=1):
        assert f"[{number}] general, 10.5°, body 12, {names[rule]}: not resolved with 120 runs" in text
