"""``rig records …``: list the record suites and the user's library, inspect a record, import records.

Commands (``--json`` prints exactly one JSON object on stdout; errors go to stderr as ``error: …``, exit
code 2; ``--library DIR`` overrides the library directory, see `rig.records.library`):

* ``rig records list [--json]`` — the suites (FEMA P695 and ``library``) and their component counts;
* ``rig records list SUITE [--json]`` — name, dt [s], npts, duration [s], PGA [g] per component;
* ``rig records show SPEC [--dt S] [--units U] [--accept-vertical] [--json]`` — one record (``SUITE:NAME``,
  ``library:NAME``, a record file or ``H1+H2[+UP]``, see `rig.records`) with its provenance;
* ``rig records import FILE_OR_PAIR... [--name NAME] [--dt S] [--units U] [--replace] [--accept-vertical]
  [--json]`` — store records in the library; reports each name, file, npts, dt and PGA.

``--accept-vertical``: a file that holds only a vertical component may drive surge alone (refused otherwise).

``rig.cli`` calls `register` to mount the group on the main application.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.table import Table
from rich.text import Text

from rig.cli._common import console, emit_json, fail

if TYPE_CHECKING:
    from rig.records import GroundMotion, Imported

records_app = typer.Typer(
    name="records",
    help="Earthquake records: the FEMA P695 suites, record files and your record library.",
    no_args_is_help=True,
    add_completion=False,
)

JsonOption = Annotated[bool, typer.Option("--json", help="Print one JSON object on stdout.")]
LibraryOption = Annotated[
    Path | None,
    typer.Option(
        "--library", help="Record library directory (default: $RIG_RECORD_LIBRARY or the user data directory)."
    ),
]
DtOption = Annotated[float | None, typer.Option("--dt", help="Time step in seconds of a file that does not give one.")]
AcceptVerticalOption = Annotated[
    bool,
    typer.Option(
        "--accept-vertical",
        help="Let a file that holds only a vertical component drive surge alone (refused otherwise).",
    ),
]
UnitsOption = Annotated[
    str | None, typer.Option("--units", help="Acceleration unit of a file that does not give one: g, cm/s/s, m/s/s.")
]


def register(app: typer.Typer) -> None:
    """Add the ``records`` command group (``list``, ``show``, ``import``) to ``app``."""
    app.add_typer(records_app, name="records")


def _summary(motion: GroundMotion) -> dict[str, Any]:
    """Name, dt [s], npts, duration [s] and PGA [g] of each component of a motion (None where absent)."""
    return {
        "name": motion.name,
        "dt": motion.dt,
        "npts": motion.npts,
        "duration": motion.duration,
        "pga": motion.pga,
        "pga_h2": motion.pga_h2,
        "pga_v": motion.pga_v,
        "units": motion.units,
    }


def _suites_overview(library: Path | None) -> dict[str, Any]:
    """Every suite (the library last) with its component count, the aliases and the total."""
    from rig.records import LIBRARY, SUITE_ALIASES, SUITES, library_dir, library_names, load_records

    suites: list[dict[str, Any]] = [{"name": s, "components": len(load_records(s))} for s in SUITES]
    suites.append({"name": LIBRARY, "components": len(library_names(library)), "path": str(library_dir(library))})
    return {
        "suites": suites,
        "aliases": {alias: list(members) for alias, members in SUITE_ALIASES.items()},
        "total_components": sum(s["components"] for s in suites),
    }


def _suite_listing(suite: str, library: Path | None) -> dict[str, Any]:
    """The components of one suite (or alias, or the library) with their summaries."""
    from rig.records import LIBRARY, SUITE_ALIASES, SUITES, RecordError, library_dir, load_library, load_records

    if suite == LIBRARY:
        components = [_summary(m) for m in load_library(library)]
        return {"suite": suite, "path": str(library_dir(library)), "count": len(components), "components": components}
    if suite not in SUITES and suite not in SUITE_ALIASES:
        valid = ", ".join((*SUITES, *SUITE_ALIASES, LIBRARY))
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
    console.print(table)
    for alias, members in data["aliases"].items():
        console.print(Text(f"alias: {alias} = {' + '.join(members)}"))
    library = next(row for row in data["suites"] if "path" in row)  # the library row has a path
    console.print(Text(f"library: {library['path']}"))
    console.print(Text("components of a suite: rig records list SUITE"))


def _pga_columns(components: list[dict[str, Any]]) -> list[tuple[str, str]]:
    """(key, header) of the PGA columns to show: horizontal always, h2 and vertical where any has them."""
    columns = [("pga", "PGA [g]")]
    columns += [(key, head) for key, head in (("pga_h2", "PGA h2 [g]"), ("pga_v", "PGA v [g]"))
                if any(c[key] is not None for c in components)]
    return columns


def _print_listing(data: dict[str, Any]) -> None:
    noun = "component" if data["count"] == 1 else "components"
    title = f"{data['suite']} ({data['count']} {noun})" + (f" in {data['path']}" if "path" in data else "")
    table = Table(title=Text(title))
    table.add_column("name", overflow="fold")
    pga_columns = _pga_columns(data["components"])
    for header in ("dt [s]", "npts", "duration [s]", *(head for _, head in pga_columns)):
        table.add_column(Text(header), justify="right")
    for c in data["components"]:
        cells = (f"{c['dt']:g}", str(c["npts"]), f"{c['duration']:.2f}")
        pgas = ("" if c[key] is None else peak(c[key]) for key, _ in pga_columns)
        table.add_row(Text(c["name"]), *cells, *pgas)
    console.print(table)


def _print_record(data: dict[str, Any]) -> None:
    table = Table(title=Text(data["name"]), show_header=False)
    table.add_column("field", style="bold", no_wrap=True)
    table.add_column("value", overflow="fold")
    rows: list[tuple[str, str]] = [
        ("dt [s]", f"{data['dt']:g}"),
        ("npts", str(data["npts"])),
        ("duration [s]", f"{data['duration']:.3f}"),
        ("PGA [g]", peak(data["pga"])),
    ]
    if data["pga_h2"] is not None:
        rows.append(("PGA horizontal 2 [g]", peak(data["pga_h2"])))
    if data["pga_v"] is not None:
        rows.append(("PGA vertical [g]", peak(data["pga_v"])))
    rows += [(key, _fmt(value)) for key, value in data["provenance"].items()]
    for key, value in rows:
        table.add_row(Text(key), Text(value))
    console.print(table)


def peak(value: float) -> str:
    """A peak acceleration [g] with 4 significant digits: ``0.3481``, ``1.25``, ``2.7e-06`` (never ``0.0000``)."""
    return f"{value:.4g}"


def _fmt(value: Any) -> str:
    """Provenance value as display text (nested values as JSON)."""
    if isinstance(value, float) and math.isfinite(value):
        return f"{value:g}"
    if isinstance(value, dict | list):
        return json.dumps(value, indent=1)
    return str(value)


def _imported(entry: Imported, source: str) -> dict[str, Any]:
    """JSON view of one imported record."""
    return {**_summary(entry.motion), "path": str(entry.path), "replaced": entry.replaced, "source": source}


def _print_imported(data: dict[str, Any]) -> None:
    table = Table(title=Text(f"Imported into {data['library']}"))
    for header in ("name", "file", "npts", "dt [s]", "PGA [g]", "source"):
        numeric = header in ("npts", "dt [s]", "PGA [g]")
        table.add_column(Text(header), justify="right" if numeric else "left", overflow="fold")
    for r in data["imported"]:
        name = r["name"] + (" (replaced)" if r["replaced"] else "")
        table.add_row(Text(name), Text(Path(r["path"]).name), str(r["npts"]), f"{r['dt']:g}", peak(r["pga"]),
                      Text(r["source"]))
    console.print(table)


@records_app.command("list")
def list_command(
    suite: Annotated[
        str | None,
        typer.Argument(
            help="A suite (fema-farfield, fema-nearfield, library) or alias (fema); omit for all suites."
        ),
    ] = None,
    library: LibraryOption = None,
    as_json: JsonOption = False,
) -> None:
    """List the record suites, or the components of SUITE with dt, npts, duration and PGA."""
    from rig.records import RecordError

    try:
        data = _suites_overview(library) if suite is None else _suite_listing(suite, library)
    except RecordError as exc:
        fail(str(exc))
    if as_json:
        emit_json(data, allow_nan=False)
    elif suite is None:
        _print_overview(data)
    else:
        _print_listing(data)


@records_app.command("show")
def show_command(
    spec: Annotated[
        str,
        typer.Argument(
            help="SUITE:NAME (e.g. fema-farfield:NORTHR/MUL009), library:NAME, a record file "
            "(.AT2, .txt, .dat, .acc, .csv, .h5, COSMOS .V1/.V2) or H1+H2[+UP]."
        ),
    ],
    dt: DtOption = None,
    units: UnitsOption = None,
    library: LibraryOption = None,
    accept_vertical: AcceptVerticalOption = False,
    as_json: JsonOption = False,
) -> None:
    """Show one record: name, dt, npts, duration, PGA and provenance."""
    from rig.records import RecordError, load_record

    try:
        motion = load_record(spec, dt=dt, units=units, library=library, accept_vertical=accept_vertical)
    except RecordError as exc:
        fail(str(exc))
    data = {**_summary(motion), "provenance": motion.provenance}
    if as_json:
        emit_json(data, allow_nan=False)
    else:
        _print_record(data)


@records_app.command("import")
def import_command(
    sources: Annotated[
        list[str],
        typer.Argument(
            metavar="FILE_OR_PAIR",
            help="Record files (.AT2, .txt, .dat, .acc, .csv, .h5, COSMOS .V1/.V2) or H1+H2[+UP] component sets.",
        ),
    ],
    name: Annotated[
        str | None, typer.Option("--name", help="Library name (one record only; default: the file stem).")
    ] = None,
    dt: DtOption = None,
    units: UnitsOption = None,
    library: LibraryOption = None,
    replace: Annotated[bool, typer.Option("--replace", help="Replace a library record of the same name.")] = False,
    accept_vertical: AcceptVerticalOption = False,
    as_json: JsonOption = False,
) -> None:
    """Store records in the library (as record .h5 files; the source files are not changed)."""
    from rig.records import RecordError, import_records, library_dir

    try:
        entries = import_records(sources, name=name, dt=dt, units=units, directory=library, replace=replace,
                                 accept_vertical=accept_vertical)
    except RecordError as exc:
        fail(str(exc))
    data = {
        "library": str(library_dir(library)),
        "count": len(entries),
        "imported": [_imported(entry, source) for entry, source in zip(entries, sources, strict=True)],
    }
    if as_json:
        emit_json(data, allow_nan=False)
    else:
        _print_imported(data)
