"""``rig table check URL [--rig-config FILE] [--json]``: what the table is, before anything moves.

CANopen (``canopen://…``): each leg drive read without configuring or enabling it (``drivers.canopen.survey``) —
identity, device type, supported modes, position unit and factors, how it is watched, which optional objects and
profile features are used and which are missing, and why it cannot be driven; exit 0 when all six can be driven,
:data:`~rig.cli._common.EXIT_REFUSED` (3) when not. MAVLink and zenoh tables: observed (``observe=True``: connected
without claiming it, so a table another host owns is looked at, not taken, and its owner's run goes on), their
status and link statistics as the controller reports them; exit 0 when the table can be driven (idle, or faulted:
ARM clears the faults), 3 when it cannot be connected or is in use (armed, moving, stopping: :data:`IN_USE_STATES`).
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
            options: dict[str, Any] = {"observe": True, **({"key_file": str(key_file)} if key_file else {})}
            with open_table(url, **options) as table:
                status = table.wait_for_status(lambda _: True, STATUS_WAIT_S)
                out["link"] = _plain(table.link_stats())
            out["transport"] = url.split(":", 1)[0].lower()
            out["claimed"] = False
            out["status"] = {"state": status.state, "faults": list(status.faults),
                             "pose": [float(v) for v in status.pose], "buffer_capacity": status.buffer_capacity,
                             "virtual_watchdog_s": status.virtual_watchdog_s, "inputs": list(status.inputs)}
            in_use = IN_USE_STATES.get(status.state)
            if in_use is not None:
                out["in_use"] = f"{status.state}: {in_use}"
                drivable = False
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


AT_HOME = 1e-4
"""A pose within this of zero [m, rad] is shown as "at home"."""

STATUS_WAIT_S = 5.0
"""How long [s] a connected MAVLink or zenoh table is given to send its first status."""

IN_USE_STATES = {
    "armed": "a host has armed it (arming claims the table)",
    "tilting": "a host is tilting it",
    "streaming": "a host is playing a run on it",
    "homing": "a host is moving it home",
    "stopping": "it is stopping (its host's STOP, a watchdog or a fault)",
    "emergency_stopped": "it was emergency-stopped: ARM it only after the operator's check",
}
"""States in which a MAVLink or zenoh table cannot be driven by this host now, and why. ``idle`` and ``faulted``
(ARM clears the latched faults) can be driven once this host claims the table, which ``rig run`` does at connect."""


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
        status = out["status"]
        pose = status["pose"]
        at_home = max(abs(v) for v in pose) <= AT_HOME if pose else True
        shown = "at home" if at_home else "[" + ", ".join(f"{v:.4g}" for v in pose) + "] (m, rad)"
        console.print(f"{out['transport']} table {out['url']}: state {status['state']}, faults "
                      f"{' '.join(status['faults']) or 'none'}, pose {shown}, buffer "
                      f"capacity {status['buffer_capacity'] or 'not reported'}, "
                      f"{'virtual time' if status['virtual_watchdog_s'] else 'real time'}, inputs "
                      f"{' '.join(status['inputs']) or 'none'}", highlight=False, markup=False)
        console.print("observed without claiming it (a monitor: nothing sent could move it or take it from its "
                      "owner; rig run claims it at connect and names an owning host)", highlight=False, markup=False)
        if "in_use" in out:
            console.print(f"  in use: {out['in_use']}", highlight=False, markup=False)
        console.print(f"link {out['link']}", highlight=False, markup=False)
    console.print("the table can be driven" if out["drivable"] else
                  "the table cannot be driven now" if "in_use" in out else "the table cannot be driven",
                  highlight=False, markup=False)

