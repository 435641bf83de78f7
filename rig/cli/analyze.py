"""``rig analyze SESSION.h5``: the models re-run on the measured plate motion of every completed run, predicted
beside observed overturn directions, and the Fig. 13 comparison (`rig.analyze`). Stores the result in the session
file's ``analysis`` groups (raw data untouched; re-running replaces them) unless ``--no-write``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich import box
from rich.console import JustifyMethod, RenderableType
from rich.table import Table
from rich.text import Text

from rig.cli._common import console, emit_json, fail, fail_with, require_file

if TYPE_CHECKING:
    from rig.analyze import SessionAnalysis

MODEL_CHOICES = {"rocking": ("rocking",), "general": ("general",), "both": ("rocking", "general")}


def _direction(d: int) -> str:
    return {1: "+1 low", -1: "-1 high", 0: "0"}[d]


def _pct(x: float | None) -> str:
    return "–" if x is None or math.isnan(x) else f"{100 * x:.0f}"


def _seconds(t: float) -> str:
    return "" if math.isnan(t) else f" @{t:.2f}s"


def predictions_table(result: SessionAnalysis) -> Table:
    """One row per run and body: observed, then each model's prediction (``*`` where it differs)."""
    table = Table(box=box.SIMPLE_HEAD, title="Predicted (from the measured motion) beside observed overturns")
    columns: tuple[tuple[str, JustifyMethod], ...] = (
        ("run", "left"), ("record", "left"), ("β°", "right"), ("body", "left"), ("observed", "left"))
    for name, justify in columns:
        table.add_column(name, justify=justify)
    for model in result.models:
        table.add_column(model, justify="left")
    for run in result.runs:
        by_body: dict[int, dict[str, Any]] = {}
        for p in run.predictions:
            by_body.setdefault(p.body_id, {"name": p.body_name, "observed": p.observed, "t": p.t_observed})[
                p.model] = p
        for body_id, row in by_body.items():
            cells = []
            for model in result.models:
                prediction = row.get(model)
                cells.append("–" if prediction is None else
                             f"{_direction(prediction.direction)}{_seconds(prediction.t_overturn)}"
                             f"{' *' if prediction.direction != prediction.observed else ''}")
            table.add_row(run.run, run.record, f"{run.angle_deg:g}", f"{body_id} {row['name']}".strip(),
                          f"{_direction(row['observed'])}{_seconds(row['t'])}", *cells)
    return table


WIDTH = 100
"""Columns the Fig. 13 tables fit in (a terminal of this width shows every cell on one line)."""


def _verdict_cell(row: Mapping[str, Any], label: str, notes: list[str]) -> str:
    """A row's verdict for a table cell: the verdict itself, and where its words are longer (``not resolved with
    26 runs (about 410 would)``) a footnote number with the words added to ``notes`` under ``label``."""
    from rig.analyze.fig13 import verdict_words

    verdict = str(row["verdict"])
    words = verdict_words(verdict, int(row["body_id"]), int(row["runs"]), int(row["runs_to_resolve"]))
    if words == verdict:
        return verdict
    notes.append(f"[{len(notes) + 1}] {label}: {words}")
    return f"{verdict} [{len(notes)}]"


def _label(model: str, angle_deg: float, body_id: int, rule: str = "") -> str:
    """``rocking, 5°, body 2`` (``…, fitted`` under an impact rule): where a footnote belongs."""
    body = "average" if body_id == 0 else f"body {body_id}"
    return ", ".join([model, f"{angle_deg:g}°", body, *([RULE_NAMES.get(rule, rule)] if rule else [])])


def fig13_tables(result: SessionAnalysis) -> list[RenderableType]:
    """The Fig. 13 comparison in two tables of at most `WIDTH` columns: per model, angle and body (and the body
    average) the rates [%], their difference and the equivalence verdict, the verdicts' long words as footnotes;
    then the counts and the paired tests."""
    margin = 100 * result.margin
    rates = Table(box=box.SIMPLE_HEAD, title="Fig. 13 — controlled overturning rate, analysis vs experiment",
                  caption=f"COR = overturns towards the low side / overturns (%), A analysis, E experiment [95 % "
                          f"interval: Wilson's, or the cluster bootstrap over records where records are shared]; "
                          f"n = runs (average: body-runs); diff = A − E (percentage points) [90 % interval]; "
                          f"verdict: equivalence within ±{margin:g} points (two one-sided tests at 5 %)")
    for name in ("model", "β°", "body", "n", "COR A", "COR E", "diff", "verdict"):
        rates.add_column(name, justify="left" if name in ("model", "body", "verdict") else "right")
    counts = Table(box=box.SIMPLE_HEAD, title="Fig. 13 — the counts and the paired tests",
                   caption="ovt = overturned, low = towards the low side; McNemar = the discordant pairs and their "
                           "exact p, on the side (low/high vs high/low) and on overturning (analysis only vs "
                           "experiment only)")
    for name in ("model", "β°", "body", "ovt A", "low A", "ovt E", "low E", "McNemar side", "McNemar ovt"):
        counts.add_column(name, justify="left" if name in ("model", "body") else "right")
    notes: list[str] = []
    for row in result.fig13:
        diff = "–" if math.isnan(row.difference) else (
            f"{100 * row.difference:+.0f} [{100 * row.difference_low:+.0f}, {100 * row.difference_high:+.0f}]")
        where = (row.model, f"{row.angle_deg:g}", "average" if row.body_id == 0 else str(row.body_id))
        style = "bold" if row.body_id == 0 else None
        rates.add_row(*where, str(row.runs), _rate(row.cor_analysis, row.cor_analysis_low, row.cor_analysis_high),
                      _rate(row.cor_experiment, row.cor_experiment_low, row.cor_experiment_high), diff,
                      _verdict_cell(row.to_json(), _label(row.model, row.angle_deg, row.body_id), notes),
                      style=style)
        counts.add_row(*where, str(row.overturned_analysis), str(row.towards_low_analysis),
                       str(row.overturned_experiment), str(row.towards_low_experiment),
                       _mcnemar(row.low_high, row.high_low, row.p_direction),
                       _mcnemar(row.analysis_only, row.experiment_only, row.p_overturn), style=style)
    return [rates, *(Text(note) for note in notes), counts]


RULE_NAMES = {"plastic": "plastic", "housner": "Housner's", "fit": "fitted"}
"""Names of the impact rules compared (``--restitution all``)."""


def rules_tables(result: SessionAnalysis) -> list[RenderableType]:
    """Fig. 13 with the models under plastic, Housner's and fitted restitution (``--restitution all``), in at most
    `WIDTH` columns: per model, angle and body the experiment's COR, then one line per rule with the analysis's
    COR and the verdict; the verdicts' long words as footnotes."""
    from rig.analyze.fig13 import side_by_side

    groups = side_by_side(row.to_json() for row in result.fig13)
    rules = list(dict.fromkeys(rule for *_, by_rule in groups for rule in by_rule))
    table = Table(box=box.SIMPLE_HEAD, title="Fig. 13 — plastic, Housner's and fitted restitution, rule by rule",
                  caption=f"COR [%] [95 % interval], A analysis, E experiment; verdict: equivalence of the "
                          f"analysis's COR with the experiment's within ±{100 * result.margin:g} points (two "
                          f"one-sided tests at 5 %); the counts, differences and McNemar tests per rule: --json, "
                          f"or rig report")
    for name in ("model", "β°", "body", "COR E", "restitution", "COR A", "verdict"):
        table.add_column(name, justify="left" if name in ("model", "body", "restitution", "verdict") else "right")
    notes: list[str] = []
    for model, angle, body_id, by_rule in groups:
        first = next(iter(by_rule.values()))
        where = [model, f"{angle:g}", "average" if body_id == 0 else str(body_id),
                 _rate(_nan(first["cor_experiment"]), _nan(first["cor_experiment_low"]),
                       _nan(first["cor_experiment_high"]))]
        for rule in rules:
            row = by_rule.get(rule)
            cells = ["–", "–"] if row is None else [
                _rate(_nan(row["cor_analysis"]), _nan(row["cor_analysis_low"]), _nan(row["cor_analysis_high"])),
                _verdict_cell(row, _label(model, angle, body_id, rule), notes)]
            table.add_row(*where, RULE_NAMES.get(rule, rule), *cells, style="bold" if body_id == 0 else None)
            where = ["", "", "", ""]
        table.add_section()
    return [table, *(Text(note) for note in notes)]


def _nan(value: float | None) -> float:
    """A JSON rate (None when undefined) as a float (NaN)."""
    return math.nan if value is None else float(value)


def _mcnemar(b: int, c: int, p: float) -> str:
    """Discordant counts and McNemar's exact p, ``–`` on the average row."""
    return "–" if math.isnan(p) else f"{b}/{c} p={p:.2f}"


def _rate(value: float, low: float, high: float) -> str:
    """A COR [%] with its interval, ``–`` when undefined."""
    return "–" if math.isnan(value) else f"{_pct(value)} [{100 * low:.0f}–{100 * high:.0f}]"


def print_analysis(result: SessionAnalysis, console: Any) -> None:
    """Everything `rig analyze` prints without ``--json``."""
    console.print(f"[bold]{result.path}[/]: {len(result.runs)} run(s) analysed, models {', '.join(result.models)}"
                  f" ({result.solver} solver, restitution {result.restitution})"
                  + (", stored in its analysis groups" if result.written else ""))
    for body in result.fitted_restitution.values():
        console.print(f"  body {body.body_id}: restitution {body.label()}", highlight=False)
    for skipped in result.skipped:
        console.print(f"  skipped run {skipped.run} ({skipped.status}): {skipped.reason}", highlight=False)
    degraded = sum(1 for skipped in result.skipped if skipped.status == "degraded")
    if degraded:
        console.print(f"  {degraded} degraded run(s) left out of Fig. 13 (--include-degraded takes them)",
                      highlight=False)
    for run in result.runs:
        for body_id, reason in run.skipped_bodies:
            console.print(f"  run {run.run}: body {body_id} not analysed: {reason}", highlight=False)
        for note in run.input.notes:
            console.print(f"  run {run.run}: {note}", highlight=False)
        for sensor, samples in run.clipped.items():
            if samples:
                console.print(f"  run {run.run}: [bold]clipped[/]: accelerometer {sensor} at its full scale in "
                              f"{samples} sample(s); the models were given a cut signal", highlight=False)
    console.print(predictions_table(result))
    from rig.analyze.session import ALL_RULES

    for part in rules_tables(result) if result.restitution == ALL_RULES else fig13_tables(result):
        console.print(part, highlight=False)
    for model in result.models:
        a = result.agreement[model]
        diff = result.max_difference.get(model)
        verdicts = ", ".join(f"{v} {n}" for v, n in result.verdicts.get(model, {}).items() if n)
        console.print(
            f"{model}: max |COR difference| of a body at an angle "
            f"{'undefined (no overturn on both sides)' if diff is None else f'{100 * diff:.1f} points'} "
            f"(the paper: ≤ 5); equivalence within ±{100 * result.margin:g} points per body and angle: "
            f"{verdicts or 'no rate'}; "
            f"case by case {a.agree}/{a.cases} agree — overturned in both {a.overturned_both} "
            f"(same side {a.same_direction}), analysis only {a.overturned_analysis_only}, experiment only "
            f"{a.overturned_experiment_only}, neither {a.overturned_neither}", highlight=False)


def register(app: typer.Typer) -> None:
    """Add ``rig analyze``."""

    @app.command("analyze")
    def analyze_cmd(
        path: Annotated[Path, typer.Argument(metavar="SESSION.h5", help="a session file written by rig run")],
        model: Annotated[str, typer.Option(help="rocking | general | both")] = "both",
        solver: Annotated[str, typer.Option(help="fast | reference")] = "fast",
        restitution: Annotated[str, typer.Option(help="the models' impact rule: 0 (plastic, the paper's), "
                                                      "'housner', a number in [0, 1], 'fit' (each body's "
                                                      "from its measured tilts), or 'all' (plastic, Housner's "
                                                      "and fitted side by side)")] = "0",
        sensor: Annotated[str | None, typer.Option(help="use this accelerometer only (default: the mean of all)")
                          ] = None,
        margin: Annotated[float, typer.Option(help="equivalence margin of the Fig. 13 verdicts [percentage "
                                                   "points]")] = 5.0,
        write: Annotated[bool, typer.Option("--write/--no-write", help="store the result in the session file")
                         ] = True,
        include_degraded: Annotated[bool, typer.Option("--include-degraded", help="also analyse the runs logged "
                                                       "degraded (an underrun, late setpoints, lost samples, a "
                                                       "fault while the table moved)")] = False,
        as_json: Annotated[bool, typer.Option("--json", help="print one JSON object")] = False,
    ) -> None:
        """Re-run the models on each completed run's measured plate motion; predicted beside observed overturns
        and the Fig. 13 comparison (COR per angle and body, analysis against experiment). Degraded runs are left
        out (and counted) unless --include-degraded."""
        if model not in MODEL_CHOICES:
            fail(f"--model {model!r}: expected one of {', '.join(MODEL_CHOICES)}")
        try:
            impact: float | str = (restitution.lower() if restitution.lower() in ("housner", "fit", "all")
                                   else float(restitution))
        except ValueError:
            fail(f"--restitution {restitution!r}: expected 0, 'housner', a number in [0, 1], 'fit' or 'all'")
        require_file(path, "session file")
        from analysis.errors import AnalysisInputError
        from rig.analyze import analyze_session
        from rig.session import SessionError

        try:
            result = analyze_session(path, MODEL_CHOICES[model], solver, sensor=sensor, restitution=impact,
                                     margin=margin / 100.0, write=write, include_degraded=include_degraded)
        except (SessionError, AnalysisInputError, OSError) as exc:
            fail_with(exc)
        if as_json:
            emit_json(result.to_json())
            return
        print_analysis(result, console)
