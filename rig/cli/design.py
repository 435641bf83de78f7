"""``rig design``: the plate inclination that reaches a target controlled-overturning rate.

Inverts the paper's Eq. 13 (SCOR, body-specific, default) or Eq. 11 (GCOR) with the paper's
coefficients (``analysis.design``) or those fitted by a study (``--study STUDY.h5`` or a ``--json`` output).
Angles are in degrees at the CLI; the confidence is a fraction.
``--json`` prints exactly one JSON object on stdout (docs/architecture.md §7); errors go to stderr, exit 2.
"""

from __future__ import annotations

import json
import math
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, cast

import typer
from rich.table import Table

from analysis.body import Body
from analysis.errors import AnalysisInputError
from rig.cli._common import EXIT_USAGE, console, emit_json, err_console, print_error

if TYPE_CHECKING:
    from analysis.design import Equation


class EquationName(StrEnum):
    """The two design equations of the paper."""

    SCOR = "SCOR"
    GCOR = "GCOR"


def study_coefficients(path: Path, equation: Equation) -> tuple[float, ...]:
    """The fitted coefficients of ``equation`` from a study file (``rig study -o STUDY.h5``) or a saved
    ``rig study --json`` output."""
    from rig.study_file import StudyFileError, is_study_file, read_study

    if is_study_file(path):
        try:
            return read_study(path).coefficients(equation)
        except StudyFileError as exc:
            raise AnalysisInputError(f"--study {exc}") from None
    try:
        summary = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise AnalysisInputError(f"--study {path}: cannot read a `rig study --json` output: {exc}") from None
    key = equation.lower()
    fit = summary.get(key) if isinstance(summary, dict) else None
    names = ("k1", "k2", "k3", "c2") if equation == "SCOR" else ("c1", "c2")
    if not isinstance(fit, dict) or not all(isinstance(fit.get(n), int | float) for n in names):
        raise AnalysisInputError(f"--study {path}: no fitted {equation} coefficients ({', '.join(names)}) "
                                 f"under key {key!r}" + (f": {fit['error']}" if isinstance(fit, dict)
                                                         and "error" in fit else ""))
    return tuple(float(fit[n]) for n in names)


def design_result(body: Body, confidence: float, equation: Equation = "SCOR",
                  fitted: tuple[float, ...] | None = None) -> dict[str, object]:
    """The ``rig design --json`` object for ``body`` and ``confidence`` (fraction), with the paper's
    coefficients or ``fitted`` ones ((k1, k2, k3, c2) for SCOR, (c1, c2) for GCOR)."""
    from analysis.design import PAPER_GCOR, PAPER_SCOR, design_angle, design_coefficients

    beta = design_angle(body, confidence, equation, fitted)
    c1, c2 = design_coefficients(body, equation, fitted)
    coeffs = fitted or ((*PAPER_SCOR, c2) if equation == "SCOR" else PAPER_GCOR)
    names = ("k1", "k2", "k3", "c2") if equation == "SCOR" else ("c1", "c2")
    coefficients = dict(zip(names, coeffs, strict=True))
    return {
        "angle_deg": math.degrees(beta),
        "angle_rad": beta,
        "equation": equation,
        "c1": c1,
        "c2": c2,
        "confidence": confidence,
        "body": {"b": body.b, "h": body.h},
        "coefficients": coefficients,
        "source": "fitted" if fitted else "paper",
        "limit": 0.5 + c2,
    }


def _print_table(body: Body, result: dict[str, object]) -> None:
    table = Table(title=f"Design inclination ({result['equation']})", show_header=False)
    table.add_column("quantity")
    table.add_column("value", justify="right")
    table.add_row("body b × h", f"{body.b:g} m × {body.h:g} m")
    table.add_row("target COR", f"{100 * cast(float, result['confidence']):.4g} %")
    table.add_row("inclination", f"{result['angle_deg']:.3f}° ({result['angle_rad']:.5f} rad)")
    table.add_row("c1, c2", f"{result['c1']:.5f} rad, {result['c2']:g}")
    table.add_row("COR limit (0.5 + c2)", f"{100 * cast(float, result['limit']):.4g} %")
    console.print(table)


def design(
    body: Annotated[str, typer.Option("--body", help="Body b×h in metres, e.g. 0.10x0.50.")],
    confidence: Annotated[
        float,
        typer.Option("--confidence", help="Target controlled-overturning rate as a fraction, e.g. 0.95."),
    ],
    equation: Annotated[
        EquationName,
        typer.Option(
            "--equation", case_sensitive=False, help="SCOR (Eq. 13, body-specific) or GCOR (Eq. 11)."
        ),
    ] = EquationName.SCOR,
    study: Annotated[
        Path | None,
        typer.Option("--study", help="Use the coefficients fitted by a study: a `rig study -o STUDY.h5` file "
                                "or a `rig study --json` output."),
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object on stdout.")] = False,
) -> None:
    """The smallest plate inclination whose controlled-overturning rate reaches CONFIDENCE."""
    try:
        parsed = Body.parse(body)
        if not parsed.centred:
            raise AnalysisInputError(f"body {body!r}: the design equations (Eqs. 11, 13) are fitted to uniform blocks "
                                     "(centre of mass in the middle): give BxH without ;cg=")
        eq: Equation = equation.value
        fitted = study_coefficients(study, eq) if study is not None else None
        result = design_result(parsed, confidence, eq, fitted)
    except AnalysisInputError as exc:
        print_error(err_console, "rig design: error", str(exc))  # its own prefix since it was written
        raise typer.Exit(EXIT_USAGE) from None
    if as_json:
        emit_json(result, allow_nan=False)
    else:
        _print_table(parsed, result)


def register(app: typer.Typer) -> None:
    """Add the ``design`` command to ``app``."""
    app.command("design")(design)
