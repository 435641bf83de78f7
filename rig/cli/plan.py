"""``rig plan SEQUENCE.toml``: before a campaign runs, the analytical study of its bodies, angles and records as the
table will play them — the overturns to expect per body and angle — and the runs (or repetitions) the Fig. 13
equivalence verdict needs within a margin at a power (`rig.sequence.expected`).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich import box
from rich.table import Table

from rig.cli._common import console, emit_json, fail

if TYPE_CHECKING:
    from rig.sequence.expected import SequencePlan


def _optional(value: int | None) -> str:
    return "never" if value is None else str(value)


def plan_table(plan: SequencePlan) -> Table:
    """One row per angle and body: expected overturns, COR and what the verdict needs."""
    table = Table(box=box.SIMPLE_HEAD, title=f"{plan.sequence}: expected outcomes ({plan.model} model, restitution "
                                             f"{plan.restitution}) and the runs for an equivalence verdict",
                  caption=f"runs = runs of each body at the angle in the sequence ({plan.records} records × "
                          f"{plan.repetitions} repetition(s)); needed: overturns on each side and runs at the angle "
                          f"for the equivalence test within ±{100 * plan.margin:g} points to succeed with "
                          f"probability {plan.power:g} if analysis and experiment share the expected COR")
    for name in ("β°", "body", "runs", "overturned", "low", "COR %", "overturns needed", "runs needed",
                 "repetitions needed"):
        table.add_column(name, justify="left" if name == "body" else "right")
    for row in plan.bodies:
        table.add_row(f"{row.angle_deg:g}", f"{row.body_id} {row.name}", str(row.runs), str(row.overturned),
                      str(row.towards_low), "–" if row.cor is None else f"{100 * row.cor:.0f}",
                      _optional(row.overturns_needed), _optional(row.runs_needed), _optional(row.repetitions_needed))
    return table


def register(app: typer.Typer) -> None:
    """Add ``rig plan``."""

    @app.command("plan")
    def plan_cmd(
        path: Annotated[Path, typer.Argument(metavar="SEQUENCE.toml", help="a sequence file (docs/sequence-files.md)")],
        margin: Annotated[float, typer.Option(help="equivalence margin [percentage points]")] = 5.0,
        power: Annotated[float, typer.Option(help="probability of an 'equivalent' verdict when the analysis is "
                                                  "right")] = 0.8,
        model: Annotated[str, typer.Option(help="rocking | general")] = "rocking",
        restitution: Annotated[str, typer.Option(help="the models' impact rule: 0 (plastic, the paper's), "
                                                      "'housner' or a number in [0, 1]")] = "0",
        as_json: Annotated[bool, typer.Option("--json", help="print one JSON object")] = False,
    ) -> None:
        """The expected overturns per body and angle of a sequence (the analytical study of the drives the table
        will play) and how many runs or repetitions the Fig. 13 equivalence verdict needs."""
        if not 0.0 < margin < 100.0:
            fail(f"--margin {margin!r}: expected percentage points in (0, 100)")
        if not 0.0 < power < 1.0:
            fail(f"--power {power!r}: expected a probability in (0, 1)")
        if model not in ("rocking", "general"):
            fail(f"--model {model!r}: expected rocking or general")
        try:
            impact: float | str = "housner" if restitution.lower() == "housner" else float(restitution)
        except ValueError:
            fail(f"--restitution {restitution!r}: expected 0, 'housner' or a number in [0, 1]")
        from analysis.errors import AnalysisInputError
        from rig.sequence import SequenceError, load_sequence
        from rig.sequence.expected import plan_sequence

        try:
            plan = plan_sequence(load_sequence(path), margin=margin / 100.0, power=power, model=model,
                                 restitution=impact)
        except (SequenceError, AnalysisInputError) as exc:
            fail(str(exc))
        if as_json:
            emit_json(plan.to_json())
            return
        console.print(plan_table(plan))
