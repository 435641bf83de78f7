"""``rig simulate`` (one body, one record, one angle) and ``rig study`` (the paper's analytical study).

Angles are in degrees here (radians inside).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from rig.cli._common import console, emit_json, fail

if TYPE_CHECKING:
    from analysis import Body
    from analysis.study import StudyResult


def register(app: typer.Typer) -> None:
    """Add ``simulate`` and ``study``."""
    app.command("simulate")(simulate_cmd)
    app.command("study")(study_cmd)


def parse_angles(text: str) -> list[float]:
    """Degrees: ``"5"``, ``"0,4,4.5"`` or ``"START:STOP:STEP"`` (STOP included) → radians."""
    try:
        if ":" in text:
            start, stop, step = (float(v) for v in text.split(":"))
            if step <= 0:
                raise ValueError
            n = math.floor((stop - start) / step + 1e-9) + 1
            degs = [start + i * step for i in range(n)]
        else:
            degs = [float(v) for v in text.split(",")]
    except ValueError:
        fail(f"--angles {text!r}: expected degrees as '5', '0,4,4.5' or 'START:STOP:STEP' with STEP > 0")
    return [math.radians(d) for d in degs]


def parse_bodies(text: str) -> list[Body]:
    """``table1``, ``table1:1,4,12`` (1-based), ``table5`` (Table V, with its centres of gravity), ``table5:1,4``, or
    ``0.10x0.50,0.2x1.0`` (each optionally ``;cg=BCG,HCG``: ``0.099x0.493;cg=0.0515,0.243,0.2x1.0``)."""
    import re

    from analysis.body import TABLE_I, TABLE_V, Body

    try:
        for name, table in (("table1", TABLE_I), ("table5", TABLE_V)):
            if text.lower().startswith(name):
                _, _, sel = text.partition(":")
                if not sel:
                    return list(table)
                return [table[int(i) - 1] for i in sel.split(",")]
        # a comma starts a new body where the next item is a size BxH (not the second number of a cg pair)
        return [Body.parse(t) for t in re.split(r",(?=[^,;]*[x×])", text)]
    except (ValueError, IndexError) as exc:
        fail(f"--bodies {text!r}: {exc}; expected 'table1', 'table1:1,4', 'table5', 'table5:1,4' or "
             "'0.10x0.50[;cg=BCG,HCG],…'")


def simulate_cmd(
    record: Annotated[str, typer.Argument(help="a record file (.AT2, .txt, .csv, .h5, H1+H2[+UP]) or SUITE:NAME")],
    body: Annotated[str, typer.Option(help="BxH in metres, e.g. 0.10x0.50, optionally with the centre of gravity "
                                           "(b_cg from the -x corner, h_cg above the base): "
                                           "0.099x0.493;cg=0.0515,0.243")],
    angle: Annotated[float, typer.Option(help="plate inclination β [deg]")] = 0.0,
    model: Annotated[str, typer.Option(help="rocking | general")] = "rocking",
    solver: Annotated[str, typer.Option(help="fast | reference")] = "fast",
    restitution: Annotated[str, typer.Option(help="0 (plastic), 'housner' or a number in [0, 1]")] = "0",
    friction: Annotated[float, typer.Option(help="friction coefficient (general model)")] = 1.0,
    sign: Annotated[int, typer.Option(help="+1 the record as given along +x (downhill), -1 negated")] = 1,
    criterion: Annotated[str, typer.Option(help="fall (|θ| = π/2) | static (α ∓ β)")] = "fall",
    dt: Annotated[float | None, typer.Option(help="time step [s] of a text record that does not state it")] = None,
    units: Annotated[str | None, typer.Option(help="unit of a text record that does not state it (g, cm/s/s, m/s/s)")
                     ] = None,
    accept_vertical: Annotated[bool, typer.Option(help="let a lone vertical component drive surge")] = False,
    as_json: Annotated[bool, typer.Option("--json", help="print one JSON object")] = False,
) -> None:
    """One body, one record, one angle."""
    from rich.table import Table

    from analysis import AnalysisInputError, Body, simulate
    from rig.records import RecordError, load_record

    try:
        rec = load_record(record, dt=dt, units=units, accept_vertical=accept_vertical)
        b = Body.parse(body)
        if sign not in (1, -1):
            fail("--sign must be 1 or -1")
        res = simulate(b, sign * rec.acc_h, rec.dt, beta=math.radians(angle), acc_v=rec.acc_v,
                       model=model,  # type: ignore[arg-type]  # typer gives a str; simulate refuses a bad one
                       solver=solver,  # type: ignore[arg-type]  # as model
                       restitution=restitution, friction=friction,
                       criterion=criterion)  # type: ignore[arg-type]  # as model
    except (RecordError, AnalysisInputError) as exc:
        fail(str(exc))
    out = {**res.to_dict(), "record": rec.name,
           "body": {"b": b.b, "h": b.h, **({} if b.centred else {"b_cg": b.cg[0], "h_cg": b.cg[1]})},
           "angle_deg": angle, "sign": sign}
    if as_json:
        emit_json(out)
        return
    table = Table(title=f"{rec.name} · body {b.label()} · β = {angle:g}°")
    for key in ("direction", "t_overturn", "theta_max", "status", "impacts", "model", "solver"):
        table.add_row(key, str(out[key]))
    console.print(table)


def study_cmd(
    records: Annotated[str, typer.Option(help="fema | fema-farfield | fema-nearfield | SUITE:NAME | file")],
    bodies: Annotated[str, typer.Option(help="table1, table1:1,4, table5 (with its centres of gravity), table5:1,4 or "
                                             "BxH[;cg=BCG,HCG],BxH")] = "table1",
    angles: Annotated[str, typer.Option(help="degrees: '0:7:0.5' or '0,4,5'")] = "0:7:0.5",
    model: Annotated[str, typer.Option(help="rocking | general")] = "rocking",
    restitution: Annotated[str, typer.Option(help="0 (plastic), 'housner' or a number")] = "0",
    friction: Annotated[float, typer.Option(help="friction coefficient (general model)")] = 1.0,
    output: Annotated[Path | None, typer.Option("-o", "--output", help="save the study as HDF5 (STUDY.h5)")] = None,
    dask: Annotated[str | None, typer.Option("--dask", help="run on the Dask scheduler at tcp://HOST:PORT "
                                             "(default: all local cores)")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="print one JSON object")] = False,
) -> None:
    """The paper's analytical study: bodies × records × both signs × angles; COR per body and angle, Eqs. 11
    and 13 fitted beside the paper's, Eq. 12 errors and Table III's estimators."""
    from analysis.errors import AnalysisInputError
    from analysis.study import study
    from rig.records import RecordError, load_records
    from rig.study_file import StudyFileError, write_study
    from rig.study_summary import study_summary

    try:
        recs = load_records(records)
        scenes = (parse_bodies(bodies), recs, parse_angles(angles))
        if dask:
            from analysis.study_dask import study_dask

            res = study_dask(*scenes, model=model,  # type: ignore[arg-type]  # typer gives a str; study refuses a bad one
                             restitution=restitution, friction=friction, scheduler=dask)
        else:
            res = study(*scenes, model=model,  # type: ignore[arg-type]  # typer gives a str; study refuses a bad one
                        restitution=restitution, friction=friction)
        summary = study_summary(res)
        if output is not None:
            summary["output"] = str(write_study(res, summary, output))
    except (RecordError, AnalysisInputError, StudyFileError) as exc:
        fail(str(exc))
    if as_json:
        emit_json(summary)
        return
    print_cor_table(res, summary)


def print_cor_table(res: StudyResult, summary: dict | None = None) -> None:
    """COR (%) per angle (rows) and body (columns), the body average, the overturn count and Eq. 11
    with the paper's and the fitted coefficients; with the ``summary`` (`rig.study_summary`), the fitted
    coefficients beside the paper's and Table III's estimators too."""
    from rich import box
    from rich.table import Table

    from analysis.design import gcor
    from analysis.errors import AnalysisInputError
    from rig.study_summary import coefficient_table, estimator_table

    rows = res.cor()
    avg = res.average_cor()
    try:
        fit = res.fit_gcor()
    except AnalysisInputError:
        fit = None
    title = f"Controlled overturning rate (%) — {res.model} model, {res.scenes} scenes in {res.seconds:.2f} s"
    caption = "bodies: " + ", ".join(f"{i + 1}={b.b:g}x{b.h:g}" for i, b in enumerate(res.bodies))
    table = Table(box=box.SIMPLE_HEAD, title=title, caption=caption)
    table.add_column("β°", justify="right")
    for i in range(len(res.bodies)):
        table.add_column(str(i + 1), justify="right")
    for name in ("avg", "n", "Eq11", "fit"):
        table.add_column(name, justify="right", style="bold" if name == "avg" else None)

    def pct(x: float | None) -> str:
        return "–" if x is None else f"{100 * x:.0f}"

    for m, beta in enumerate(res.angles):
        cells = [pct(rows[j * len(res.angles) + m]["cor"]) for j in range(len(res.bodies))]
        table.add_row(f"{math.degrees(beta):g}", *cells, pct(avg[m]["cor"]), str(avg[m]["overturned"]),
                      pct(float(gcor(beta))), pct(float(gcor(beta, fit.c1, fit.c2))) if fit else "–")
    console.print(table)
    if summary is not None:
        console.print(coefficient_table(summary))
        console.print(estimator_table(summary))
        if "output" in summary:
            console.print(f"saved {summary['output']} ({summary['where']})", highlight=False)
    elif fit:
        console.print(f"Eq. 11 fitted to the average: c1 = {fit.c1:.4f} (95 % CI {fit.c1_ci[0]:.4f}–"
                      f"{fit.c1_ci[1]:.4f}), c2 = {fit.c2:.3f}; the paper: c1 = 0.048, c2 = 0.48.")
