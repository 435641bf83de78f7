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

from rig.cli._common import console, emit_json, fail, require_file

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
    """The Fig. 13 comparison: per model, angle and body (and the body average), counts and COR [%]."""
    table = Table(box=box.SIMPLE_HEAD, title="Fig. 13 — controlled overturning rate, analysis vs experiment",
                  caption="COR = overturns towards the low side / overturns (%), [95 % Wilson interval]; n = cases, "
                          "ovt = overturned, low = towards the low side; diff = analysis − experiment (percentage "
                          "points); p = Fisher's exact test of one rate for both (* below 0.05: beyond chance)")
    for name in ("model", "β°", "body", "n", "ovt A", "low A", "COR A", "ovt E", "low E", "COR E", "diff", "p"):
        table.add_column(name, justify="left" if name in ("model", "body") else "right")
    for row in result.fig13:
        diff = "–" if math.isnan(row.difference) else f"{100 * row.difference:+.0f}"
        p = "–" if math.isnan(row.p_value) else f"{row.p_value:.2f}{'*' if row.beyond_chance else ''}"
        table.add_row(row.model, f"{row.angle_deg:g}", "average" if row.body_id == 0 else str(row.body_id),
                      str(row.runs), str(row.overturned_analysis), str(row.towards_low_analysis),
                      _rate(row.cor_analysis, row.cor_analysis_low, row.cor_analysis_high),
                      str(row.overturned_experiment), str(row.towards_low_experiment),
                      _rate(row.cor_experiment, row.cor_experiment_low, row.cor_experiment_high), diff, p,
                      style="bold" if row.body_id == 0 else None)
    return table


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
    for run in result.runs:
        for body_id, reason in run.skipped_bodies:
            console.print(f"  run {run.run}: body {body_id} not analysed: {reason}", highlight=False)
        for note in run.input.notes:
            console.print(f"  run {run.run}: {note}", highlight=False)
    console.print(predictions_table(result))
    console.print(fig13_table(result))
    for model in result.models:
        a = result.agreement[model]
        diff = result.max_difference.get(model)
        differ, tested = result.beyond_chance.get(model, (0, 0))
        console.print(
            f"{model}: max |COR difference| of a body at an angle "
            f"{'undefined (no overturn on both sides)' if diff is None else f'{100 * diff:.1f} points'} "
            f"(the paper: ≤ 5); beyond chance (Fisher's exact p < 0.05) in {differ} of {tested} body-angle rates; "
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
                                                      "'housner', a number in [0, 1], or 'fit' (each body's "
                                                      "from its measured tilts)")] = "0",
        sensor: Annotated[str | None, typer.Option(help="use this accelerometer only (default: the mean of all)")
                          ] = None,
        write: Annotated[bool, typer.Option("--write/--no-write", help="store the result in the session file")
                         ] = True,
        as_json: Annotated[bool, typer.Option("--json", help="print one JSON object")] = False,
    ) -> None:
        """Re-run the models on each completed run's measured plate motion; predicted beside observed overturns
        and the Fig. 13 comparison (COR per angle and body, analysis against experiment)."""
        if model not in MODEL_CHOICES:
            fail(f"--model {model!r}: expected one of {', '.join(MODEL_CHOICES)}")
        try:
            impact: float | str = (restitution.lower() if restitution.lower() in ("housner", "fit")
                                   else float(restitution))
        except ValueError:
            fail(f"--restitution {restitution!r}: expected 0, 'housner', a number in [0, 1] or 'fit'")
        require_file(path, "session file")
        from analysis.errors import AnalysisInputError
        from rig.analyze import analyze_session
        from rig.session import SessionError

        try:
            result = analyze_session(path, MODEL_CHOICES[model], solver, sensor=sensor, restitution=impact,
                                     write=write)
        except (SessionError, AnalysisInputError, OSError) as exc:
            fail(str(exc))
        if as_json:
            emit_json(result.to_json())
            return
        print_analysis(result, console)
