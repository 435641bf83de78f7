"""``rig records …``: list the built-in record suites and inspect a record.

Commands (``--json`` prints exactly one JSON object on stdout; errors go to stderr, exit code 2):

* ``rig records list [--json]`` — the suites and their component counts;
* ``rig records list SUITE [--json]`` — name, dt [s], npts, duration [s], PGA [g] per component;
* ``rig records show SPEC [--json]`` — one record (``SUITE:NAME`` or an ``.AT2`` file) with provenance.

The lead's ``rig/cli.py`` calls `register` to mount the group on the main application.
"""

from __future__ import annotations

import json
import math
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table
from rich.text import Text

from rig.records import SUITE_ALIASES, SUITES, GroundMotion, RecordError, load_record, load_records

#: Exit code for a record that cannot be found or read (same as a usage error).
EXIT_RECORD_ERROR = 2

records_app = typer.Typer(
    name="records",
    help="Earthquake records: the built-in FEMA P695 suites and PEER .AT2 files.",
    no_args_is_help=True,
    add_completion=False,
)

JsonOption = Annotated[bool, typer.Option("--json", help="Print one JSON object on stdout.")]


def register(app: typer.Typer) -> None:
    """Add the ``records`` command group (``list``, ``show``) to ``app``."""
    app.add_typer(records_app, name="records")


def _fail(exc: Exception) -> typer.Exit:
    """Print ``error: …`` on stderr (plain text, no traceback) and return the exit to raise."""
    typer.echo(f"error: {exc}", err=True)
    return typer.Exit(code=EXIT_RECORD_ERROR)


def _emit_json(obj: dict[str, Any]) -> None:
    """Print one JSON object on stdout (numpy scalars converted, NaN refused)."""
    typer.echo(json.dumps(obj, default=_json_default, allow_nan=False))


def _json_default(value: Any) -> Any:
    """JSON fallback for numpy scalars and other simple values."""
    if hasattr(value, "item"):
        return value.item()
    return str(value)


def _summary(motion: GroundMotion) -> dict[str, Any]:
    """Name, dt [s], npts, duration [s] and PGA [g] of a motion."""
    return {
        "name": motion.name,
        "dt": motion.dt,
        "npts": motion.npts,
        "duration": motion.duration,
        "pga": motion.pga,
        "pga_v": motion.pga_v,
        "units": motion.units,
    }


def _suites_overview() -> dict[str, Any]:
    """Every suite with its component count, the aliases and the total."""
    suites = [{"name": s, "components": len(load_records(s))} for s in SUITES]
    return {
        "suites": suites,
        "aliases": {alias: list(members) for alias, members in SUITE_ALIASES.items()},
        "total_components": sum(s["components"] for s in suites),
    }


def _suite_listing(suite: str) -> dict[str, Any]:
    """The components of one suite (or alias) with their summaries."""
    if suite not in SUITES and suite not in SUITE_ALIASES:
        valid = ", ".join((*SUITES, *SUITE_ALIASES))
        raise RecordError(f"unknown record suite {suite!r}; valid suites: {valid}")
    components = [_summary(m) for m in load_records(suite)]
    return {"suite": suite, "count": len(components), "components": components}


def _print_overview(data: dict[str, Any]) -> None:
    table = Table(title="Record suites")
    table.add_column("suite")
    table.add_column("components", justify="right")
    for row in data["suites"]:
        table.add_row(Text(row["name"]), str(row["components"]))
    table.add_row(Text("total", style="bold"), str(data["total_components"]))
    console = Console()
    console.print(table)
    for alias, members in data["aliases"].items():
        console.print(Text(f"alias: {alias} = {' + '.join(members)}"))
    console.print(Text("components of a suite: rig records list SUITE"))


def _print_listing(data: dict[str, Any]) -> None:
    table = Table(title=Text(f"{data['suite']} ({data['count']} components)"))
    table.add_column("name")
    for header in ("dt [s]", "npts", "duration [s]", "PGA [g]"):
        table.add_column(Text(header), justify="right")
    for c in data["components"]:
        cells = (f"{c['dt']:g}", str(c["npts"]), f"{c['duration']:.2f}", f"{c['pga']:.3f}")
        table.add_row(Text(c["name"]), *cells)
    Console().print(table)


def _print_record(data: dict[str, Any]) -> None:
    table = Table(title=Text(data["name"]), show_header=False)
    table.add_column("field", style="bold", no_wrap=True)
    table.add_column("value", overflow="fold")
    rows: list[tuple[str, str]] = [
        ("dt [s]", f"{data['dt']:g}"),
        ("npts", str(data["npts"])),
        ("duration [s]", f"{data['duration']:.3f}"),
        ("PGA [g]", f"{data['pga']:.4f}"),
    ]
    if data["pga_v"] is not None:
        rows.append(("PGA vertical [g]", f"{data['pga_v']:.4f}"))
    rows += [(key, _fmt(value)) for key, value in data["provenance"].items()]
    for key, value in rows:
        table.add_row(Text(key), Text(value))
    Console().print(table)


def _fmt(value: Any) -> str:
    """Provenance value as display text."""
    if isinstance(value, float) and math.isfinite(value):
        return f"{value:g}"
    return str(value)


@records_app.command("list")
def list_command(
    suite: Annotated[
        str | None,
        typer.Argument(help="A suite (fema-farfield, fema-nearfield) or alias (fema); omit for all suites."),
    ] = None,
    as_json: JsonOption = False,
) -> None:
    """List the record suites, or the components of SUITE with dt, npts, duration and PGA."""
    try:
        data = _suites_overview() if suite is None else _suite_listing(suite)
    except RecordError as exc:
        raise _fail(exc) from None
    if as_json:
        _emit_json(data)
    elif suite is None:
        _print_overview(data)
    else:
        _print_listing(data)


@records_app.command("show")
def show_command(
    spec: Annotated[
        str, typer.Argument(help="SUITE:NAME (e.g. fema-farfield:NORTHR/MUL009) or a .AT2 file.")
    ],
    as_json: JsonOption = False,
) -> None:
    """Show one record: name, dt, npts, duration, PGA and provenance."""
    try:
        motion = load_record(spec)
    except RecordError as exc:
        raise _fail(exc) from None
    data = {**_summary(motion), "provenance": motion.provenance}
    if as_json:
        _emit_json(data)
    else:
        _print_record(data)
