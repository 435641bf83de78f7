"""``rig analyze SESSION.h5``: the models re-run on the measured plate motion of every completed run, predicted
beside observed overturn directions, and the Fig. 13 comparison (`rig.analyze`). Stores the result in the session
file's ``analysis`` groups (raw data untouched; re-running replaces them) unless ``--no-write``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich import box
from rich.table import Table

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
    for name, justify in (("run", "left"), ("record", "left"), ("β°", "right"), ("body", "left"),
                          ("observed", "left")):
        table.add_column(name, justify=justify)  # type: ignore[arg-type]
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
                p = row.get(model)
                cells.append("–" if p is None else f"{_direction(p.direction)}{_seconds(p.t_overturn)}"
                             f"{' *' if p.direction != p.observed else ''}")
            table.add_row(run.run, run.record, f"{run.angle_deg:g}", f"{body_id} {row['name']}".strip(),
                          f"{_direction(row['observed'])}{_seconds(row['t'])}", *cells)
    return table


def fig13_table(result: SessionAnalysis) -> Table:
    """The Fig. 13 comparison: per model, angle and body (and the body average), counts, COR [%], the paired test
    and the equivalence verdict."""
    margin = 100 * result.margin
    table = Table(box=box.SIMPLE_HEAD, title="Fig. 13 — controlled overturning rate, analysis vs experiment",
                  caption=f"COR = overturns towards the low side / overturns (%), [95 % interval: Wilson's, or the "
                          f"cluster bootstrap over records where records are shared]; n = runs (average: body-runs), "
                          f"ovt = overturned, low = towards the low side; diff = analysis − experiment (percentage "
                          f"points) [90 % interval]; McNemar = exact p of the paired cases on the side (low/high "
                          f"vs high/low) and on overturning (analysis only vs experiment only); verdict: "
                          f"equivalence within ±{margin:g} points (two one-sided tests at 5 %)")
    for name in ("model", "β°", "body", "n", "ovt A", "low A", "COR A", "ovt E", "low E", "COR E", "diff",
                 "McNemar side", "McNemar ovt", "verdict"):
        table.add_column(name, justify="left" if name in ("model", "body", "verdict") else "right")
    for row in result.fig13:
        diff = "–" if math.isnan(row.difference) else (
            f"{100 * row.difference:+.0f} [{100 * row.difference_low:+.0f}, {100 * row.difference_high:+.0f}]")
        table.add_row(row.model, f"{row.angle_deg:g}", "average" if row.body_id == 0 else str(row.body_id),
                      str(row.runs), str(row.overturned_analysis), str(row.towards_low_analysis),
                      _rate(row.cor_analysis, row.cor_analysis_low, row.cor_analysis_high),
                      str(row.overturned_experiment), str(row.towards_low_experiment),
                      _rate(row.cor_experiment, row.cor_experiment_low, row.cor_experiment_high), diff,
                      _mcnemar(row.low_high, row.high_low, row.p_direction),
                      _mcnemar(row.analysis_only, row.experiment_only, row.p_overturn), row.verdict_words(),
                      style="bold" if row.body_id == 0 else None)
    return table


RULE_NAMES = {"plastic": "plastic", "housner": "Housner's", "fit": "fitted"}
"""Column heads of the impact rules side by side (``--restitution all``)."""


def rules_table(result: SessionAnalysis) -> Table:
    """Fig. 13 with the models under plastic, Housner's and fitted restitution side by side (``--restitution
    all``): per model, angle and body the experiment's COR, then per rule the analysis's COR and the verdict."""
    from rig.analyze.fig13 import side_by_side, verdict_words

    groups = side_by_side(row.to_json() for row in result.fig13)
    rules = list(dict.fromkeys(rule for *_, by_rule in groups for rule in by_rule))
    table = Table(box=box.SIMPLE_HEAD, title="Fig. 13 — plastic, Housner's and fitted restitution side by side",
                  caption=f"COR [%] [95 % interval]; verdict: equivalence of the analysis's COR with the experiment's "
                          f"within ±{100 * result.margin:g} points (two one-sided tests at 5 %); the counts, "
                          f"differences and McNemar tests per rule: --json, or rig report")
    for name in ("model", "β°", "body", "COR E"):
        table.add_column(name, justify="left" if name in ("model", "body") else "right")
    for rule in rules:
        table.add_column(f"COR A {RULE_NAMES.get(rule, rule)}", justify="right")
        table.add_column(f"verdict {RULE_NAMES.get(rule, rule)}", justify="left")
    for model, angle, body_id, by_rule in groups:
        first = next(iter(by_rule.values()))
        cells = []
        for rule in rules:
            row = by_rule.get(rule)
            cells += ["–", "–"] if row is None else [
                _rate(_nan(row["cor_analysis"]), _nan(row["cor_analysis_low"]), _nan(row["cor_analysis_high"])),
                verdict_words(str(row["verdict"]), body_id, int(row["runs"]), int(row["runs_to_resolve"]))]
        table.add_row(model, f"{angle:g}", "average" if body_id == 0 else str(body_id),
                      _rate(_nan(first["cor_experiment"]), _nan(first["cor_experiment_low"]),
                            _nan(first["cor_experiment_high"])), *cells, style="bold" if body_id == 0 else None)
    return table


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
    console.print(predictions_table(result))
    from rig.analyze.session import ALL_RULES

    console.print(rules_table(result) if result.restitution == ALL_RULES else fig13_table(result))
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
