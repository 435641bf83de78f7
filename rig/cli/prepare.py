"""``rig prepare RECORD``: a record → a table-ready drive, its scale factor and governing limit.

``--json`` prints one JSON object on stdout (docs/architecture.md §7). A record or option that cannot be used
exits with code 2; a drive the table cannot play (a leg's stroke or speed, a tilt limit) exits with code 3
and names the first violation — with ``--json`` also as ``{"refused": {...}}`` on stdout.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich import box
from rich.markup import escape
from rich.table import Table

from rig.cli._common import EXIT_REFUSED, EXIT_USAGE, console, emit_json, err_console, print_error

if TYPE_CHECKING:
    from analysis.table.model import TableModel
    from rig.drive import Drive



def register(app: typer.Typer) -> None:
    """Add ``prepare`` to the main application."""
    app.command("prepare")(prepare_cmd)


def load_table(rig_config: Path | None) -> TableModel:
    """The table model from a rig configuration TOML file, or Table IV with the default hexapod."""
    from analysis.table.model import TableModel

    return TableModel() if rig_config is None else TableModel.from_toml(rig_config)


def prepare_cmd(
    record: Annotated[str, typer.Argument(help="a record file (.AT2, .txt, .csv, .h5, H1+H2[+UP]) or SUITE:NAME")],
    angle: Annotated[float, typer.Option(help="static tilt β of the plate [deg]")] = 0.0,
    rig_config: Annotated[Path | None, typer.Option(help="rig configuration TOML (default: Table IV)")] = None,
    scale: Annotated[float | None, typer.Option(help="a fixed scale factor instead of the largest that fits")] = None,
    corner: Annotated[float | None, typer.Option(help="a fixed high-pass corner [Hz] instead of automatic")] = None,
    rate: Annotated[float | None, typer.Option(help="controller rate [Hz] (default: the rig's, 1000)")] = None,
    dt: Annotated[float | None, typer.Option(help="time step [s] of a text record that does not state it")] = None,
    units: Annotated[str | None, typer.Option(help="unit of a text record that does not state it (g, cm/s/s, m/s/s)")
                     ] = None,
    plot: Annotated[Path | None, typer.Option(help="write a figure of the drive (PNG)")] = None,
    output: Annotated[Path | None, typer.Option("-o", "--output", metavar="DRIVE.h5",
                                                help="save the drive as a drive file a sequence plays (drive = "
                                                     "\"DRIVE.h5\" in a [[records]] entry); never overwritten")
                      ] = None,
    accept_vertical: Annotated[bool, typer.Option(help="let a lone vertical component drive surge")] = False,
    headroom: Annotated[str, typer.Option(help="margin the scale factor leaves on every limit for drive "
                                          "compensation, e.g. 10% (default 0)")] = "0",
    as_json: Annotated[bool, typer.Option("--json", help="print one JSON object")] = False,
) -> None:
    """Prepare a record for the table: filter, scale into the table's limits, tilt ramps, leg check; -o saves the
    drive for a sequence to play."""
    if output is not None and (output.exists() or output.is_symlink()):
        print_error(err_console, "error", f"{output}: already exists; a drive file is never overwritten, choose "
                                          "another name")
        raise typer.Exit(EXIT_USAGE)
    from analysis.table.model import TableModelError
    from rig.drive import DriveError, DriveRefusedError, parse_headroom, prepare_drive
    from rig.records import RecordError, load_record

    try:
        table = load_table(rig_config)
        motion = load_record(record, dt=dt, units=units, accept_vertical=accept_vertical)
        drive = prepare_drive(motion, angle=math.radians(angle), table=table, scale=scale, corner=corner, rate=rate,
                              headroom=parse_headroom(headroom))
    except DriveRefusedError as exc:
        if as_json:
            emit_json({"refused": {"record": record, **vars(exc.violation), "message": exc.violation.message()}},
                      allow_nan=False)
        print_error(err_console, "refused", str(exc))
        raise typer.Exit(EXIT_REFUSED) from None
    except (RecordError, DriveError, TableModelError) as exc:
        print_error(err_console, "error", str(exc))
        raise typer.Exit(EXIT_USAGE) from None
    out = drive.to_json()
    if output is not None:
        from rig.drive.file import DriveFileError, save_drive

        try:
            out["drive_file"] = str(save_drive(output, drive, {"compensated": False, "prepared_by": "rig prepare"}))
        except DriveFileError as exc:
            print_error(err_console, "error", str(exc))
            raise typer.Exit(EXIT_USAGE) from None
    if plot is not None:
        from rig.drive.plot import plot_drive  # matplotlib only when a figure is asked for

        out["plot"] = str(plot_drive(motion, drive, plot))
    if as_json:
        emit_json(out, allow_nan=False)
        return
    _print_drive(drive, out)


def _print_drive(drive: Drive, out: dict[str, Any]) -> None:
    """A table of the peaks against the limits and a line on scale, corner and timing."""
    from analysis.table.model import AXES
    from rig.records import G

    gov = out["governing"]
    limits = drive.table.limits
    table = Table(box=box.SIMPLE_HEAD, title=f"{drive.record} at β = {out['angle_deg']:g}°: "
                  f"scale factor {drive.scale_factor:.3f}")
    table.add_column("axis")
    for quantity, unit in (("displacement", "m"), ("velocity", "m/s"), ("acceleration", "g")):
        table.add_column(escape(f"{quantity} [{unit}]"), justify="right")  # "[m]" is not rich markup
    for axis in AXES:
        if axis not in drive.components:
            continue
        bounds = limits.axis(axis)
        cells = []
        for quantity in ("displacement", "velocity", "acceleration"):
            value = out["peaks"][axis][quantity]
            limit = getattr(bounds, quantity) * (1.0 / G if quantity == "acceleration" else 1.0)
            mark = "[bold]" if (axis, quantity) == (gov["axis"], gov["quantity"]) else ""
            cells.append(f"{mark}{value:.3f} / {limit:.3g} ({100 * value / limit:.0f} %)")
        table.add_row(axis, *cells)
    console.print(table)
    binding = "governs" if gov["binding"] else "is the closest limit (scale 1 fits)"
    console.print(
        f"{gov['axis']} {gov['quantity']} {binding}; high-pass corner {drive.corner_frequency:.3g} Hz "
        f"(peak acceleration kept by the filter: "
        + ", ".join(f"{a} {100 * r:.1f} %" for a, r in drive.highpass_pga_ratio.items())
        + f"); drive {drive.duration:.2f} s at {drive.rate:g} Hz, record from t = {drive.record_start:.2f} s"
        + (f"; headroom {drive.headroom:.0%} left on every limit" if drive.headroom else "")
        + (f"; plot: {out['plot']}" if "plot" in out else "")
        + (f"; drive file: {out['drive_file']}" if "drive_file" in out else ""),
        highlight=False,
    )
