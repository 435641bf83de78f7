"""``rig table check URL [--rig-config FILE] [--json]``: what the table is, before anything moves.

CANopen (``canopen://…``): each leg drive read without configuring or enabling it (``drivers.canopen.survey``) —
identity, device type, supported modes, position unit and factors, how it is watched, which optional objects and
profile features are used and which are missing, and why it cannot be driven; exit 0 when all six can be driven,
:data:`~rig.cli._common.EXIT_REFUSED` (3) when not. MAVLink and zenoh tables: connected, their status and link
statistics as the controller reports them; exit 0, or 3 when it cannot be connected.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from rig.cli import table_list
from rig.cli._common import EXIT_REFUSED, console, emit_json, err_console, fail, print_error
from rig.cli.passphrase import KeyPassphrase, use_key_passphrase


def register(app: typer.Typer) -> None:
    """Add the ``table`` group (``rig table check``, ``rig table list``) to the main application."""
    group = typer.Typer(help="The table itself: what it is, whether it can be driven, which are on the network.",
                        no_args_is_help=True)
    group.command("check")(check_cmd)
    table_list.add_list(group)
    app.add_typer(group, name="table")


def check_cmd(url: Annotated[str, typer.Argument(help="the table's URL (canopen://, mavlink://, zenoh://)")],
              rig_config: Annotated[Path | None, typer.Option("--rig-config", help="the rig TOML ([drives])")] = None,
              key_file: Annotated[Path | None, typer.Option("--key-file", help="signing key (MAVLink, zenoh)")] = None,
              as_json: Annotated[bool, typer.Option("--json", help="one JSON object on stdout")] = False,
              key_passphrase: KeyPassphrase = None) -> None:
    """Say what the table is and whether it can be driven, without enabling anything."""
    use_key_passphrase(key_passphrase, key_file)
    from analysis.table.model import TableModel, TableModelError
    from drivers.controller import TableError, open_table

    try:
        model = TableModel.from_toml(rig_config) if rig_config is not None else TableModel()
    except TableModelError as exc:
        fail(str(exc))
    drivable = True
    out: dict[str, Any] = {"url": url}
    try:
        if url.startswith("canopen:"):
            from drivers.canopen import CanopenTable

            reports = CanopenTable(url, table=model, detector=False).survey()
            out["drives"] = [report.to_dict() for report in reports]
            drivable = not any(report.problems for report in reports)
        else:
            with open_table(url, **({"key_file": str(key_file)} if key_file else {})) as table:
                status = table.status()
                out["status"] = {"state": status.state, "faults": list(status.faults)}
                out["link"] = _plain(table.link_stats())
    except (TableError, ValueError, OSError) as exc:
        if as_json:
            emit_json({**out, "drivable": False, "error": str(exc)})
        else:
            print_error(err_console, "error", str(exc))
        raise typer.Exit(EXIT_REFUSED) from None
    out["drivable"] = drivable
    if as_json:
        emit_json(out)
    else:
        _show(out)
    if not drivable:
        raise typer.Exit(EXIT_REFUSED)


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


def _show(out: dict[str, Any]) -> None:
    for drive in out.get("drives", []):
        console.print(f"leg {drive['leg']} node {drive['node_id']}: vendor 0x{drive['vendor_id']:08X} product "
                      f"0x{drive['product_code']:08X}, device type 0x{drive['device_type']:08X}, modes "
                      f"{' '.join(drive['modes'])}; unit {drive['position_unit'] or 'not stated'}, factors "
                      f"{drive['factors'] or 'none'}; watched by {drive['watch']}; profile "
                      f"{drive['profile'] or 'none (standard objects only)'} {drive['profile_features'] or ''}; "
                      f"optional used {' '.join(drive['optional_used']) or 'none'}, missing "
                      f"{' '.join(drive['optional_missing']) or 'none'}", highlight=False, markup=False)
        for problem in drive["problems"]:
            console.print(f"  cannot be driven: {problem}", highlight=False, markup=False)
    if "status" in out:
        console.print(f"status {out['status']}; link {out['link']}", highlight=False, markup=False)
    console.print("the table can be driven" if out["drivable"] else "the table cannot be driven", highlight=False,
                  markup=False)
