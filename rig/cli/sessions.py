"""``rig sessions list|show|recover``: the session files of a directory, one session's runs (also while it is
written), and recovery of a session whose writer was killed (`rig.session.recover`)."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from rig.cli._common import console, emit_json, fail, fail_with, require_file

#: What ``rig sessions list`` shows in its "writer" column for each `rig.session.writer_state`.
_STATE_SHOWN = {"writing": "writing", "crashed": "CRASHED: rig sessions recover", "closed": ""}


def run_rows(session: dict[str, Any]) -> list[dict[str, Any]]:
    """One summary per run: name, plan index, record, angle [deg], scale factor, status, accelerometer samples of
    each sensor and their span [s], overturns ``body:direction`` (operator's marked ``*``)."""
    rows = []
    for run in session["runs"]:
        accel = run.get("accel", {})
        spans = [float(a[-1, 0] - a[0, 0]) for a in accel.values() if len(a)]
        detections = " ".join(f"{d['body_id']}:{d['direction']:+d}{'*' if d['source'] == 'operator' else ''}"
                              for d in run.get("detections", []))
        attrs = run.get("attrs", {})
        rows.append({"run": run["name"], "plan": run["plan_index"] + 1, "record": run["record"],
                     "angle_deg": run["angle_deg"], "scale_factor": run["scale_factor"], "status": run["status"],
                     "samples": sum(len(a) for a in accel.values()), "seconds": max(spans, default=0.0),
                     "overturns": detections or "-", "why": str(attrs.get("degraded") or attrs.get("reason") or "")})
    return rows


def crashed_warning(path: Path) -> str | None:
    """``warning: …`` naming `rig sessions recover` if ``path`` is a session file whose writer was killed, else None
    (also for a file that is no session file: its reader says what is wrong with it)."""
    from rig.session import CRASHED, SessionError, crashed_message, writer_state

    try:
        crashed = writer_state(path) == CRASHED
    except (SessionError, OSError):
        return None
    return f"warning: {crashed_message(path)}" if crashed else None


def session_summary(path: Path) -> dict[str, Any]:
    """``rig sessions show --json``: the session's header (sequence name, created, software version, the table it
    played on, the writer's state) and :func:`run_rows` (a scale factor NaN: null)."""
    import json

    from rig.session import read_session, writer_state

    session = read_session(path)
    stored = session["attrs"].get("table")
    rows = [{**row, "scale_factor": None if row["scale_factor"] is None or math.isnan(row["scale_factor"])
             else row["scale_factor"]} for row in run_rows(session)]
    return {"path": str(path), "sequence": (session.get("sequence") or {}).get("name"),
            "created": session["created"], "software_version": session["software_version"],
            "table": json.loads(stored) if isinstance(stored, str) and stored else None,
            "writer": writer_state(path), "runs": rows}


def print_session(path: Path, console: Any) -> None:
    """The session's header and a table of its runs (and, if its writer was killed, a warning on stderr)."""
    from rich import box
    from rich.console import JustifyMethod
    from rich.table import Table

    from rig.session import read_session

    session = read_session(path)
    warning = crashed_warning(path)
    if warning:
        sys.stderr.write(warning + "\n")
    sequence = session.get("sequence") or {}
    console.print(f"[bold]{path}[/]  sequence {sequence.get('name', '?')!r}, created {session['created']}, "
                  f"software {session['software_version']}")
    table = Table(box=box.SIMPLE_HEAD)
    columns: tuple[tuple[str, JustifyMethod], ...] = (
        ("run", "left"), ("plan", "right"), ("record", "left"), ("β [°]", "right"), ("scale", "right"),
        ("status", "left"), ("accel samples", "right"), ("span [s]", "right"), ("overturns body:dir", "left"))
    for name, justify in columns:
        table.add_column(name, justify=justify)
    for row in run_rows(session):
        scale = row["scale_factor"]
        table.add_row(row["run"], str(row["plan"]), row["record"], f"{row['angle_deg']:g}",
                      "-" if scale is None or math.isnan(scale) else f"{scale:.3f}", row["status"],
                      str(row["samples"]), f"{row['seconds']:.1f}", row["overturns"],
                      style="yellow" if row["status"] == "degraded" else None)
    console.print(table)
    for row in run_rows(session):
        if row["status"] != "completed" and row["why"]:
            console.print(f"  run {row['run']} {row['status']}: {row['why']}", highlight=False)


def register(app: typer.Typer) -> None:
    """Add ``rig sessions list|show|recover``."""
    sessions = typer.Typer(help="Session files: list a directory's, show one's runs, recover a crashed one.",
                           no_args_is_help=True)
    app.add_typer(sessions, name="sessions")

    @sessions.command("list")
    def list_cmd(directory: Annotated[Path, typer.Argument(help="where the session files are")] = Path("."),
                 as_json: Annotated[bool, typer.Option("--json", help="print one JSON object")] = False) -> None:
        """The session files in DIRECTORY: created, runs and their statuses, and the writer: "writing" (a live
        rig run holds it) or "CRASHED" (its writer was killed: recover it with rig sessions recover FILE)."""
        if not directory.is_dir():
            fail(f"{directory}: no such directory")
        from rich import box
        from rich.table import Table

        from rig.session import SessionError, list_sessions

        try:
            found = list_sessions(directory)
        except (SessionError, OSError) as exc:
            fail_with(exc)
        if as_json:
            emit_json({"directory": str(directory), "sessions": found})
            return
        table = Table(box=box.SIMPLE_HEAD)
        for name in ("file", "created", "runs", "statuses", "writer"):
            table.add_column(name)
        for s in found:
            statuses = ", ".join(f"{k} {v}" for k, v in sorted(s["statuses"].items())) if isinstance(
                s["statuses"], dict) else str(s["statuses"])
            table.add_row(Path(s["path"]).name, s["created"], str(s["runs"]), statuses, _STATE_SHOWN[s["state"]])
        console.print(table)

    @sessions.command("show")
    def show_cmd(path: Annotated[Path, typer.Argument(metavar="SESSION.h5")],
                 as_json: Annotated[bool, typer.Option("--json", help="print one JSON object")] = False) -> None:
        """One session's runs: record, angle, scale factor, status, samples, overturns."""
        require_file(path, "session file")
        from rig.session import SessionError

        try:
            if as_json:
                emit_json(session_summary(path), allow_nan=False)
            else:
                print_session(path, console)
        except (SessionError, OSError) as exc:
            fail_with(exc)

    @sessions.command("recover")
    def recover_cmd(
        path: Annotated[Path, typer.Argument(metavar="SESSION.h5")],
        as_json: Annotated[bool, typer.Option("--json", help="print one JSON object")] = False,
    ) -> None:
        """After a crash (rig run killed): clear the file's writer flags so that any HDF5 program opens it, and mark
        the cut run interrupted, as rig run --resume would; no table needed, every recorded sample kept as it is.
        Refused (nothing changed) while a live writer holds the file."""
        require_file(path, "session file")
        from rig.session import SessionError, recover

        try:
            done = recover(path)
        except (SessionError, OSError) as exc:
            fail_with(exc)
        if as_json:
            emit_json(done.as_dict())
            return
        if not done.changed:
            console.print(f"{path}: nothing to recover (no writer flags set, no run left running)", highlight=False)
            return
        cut = ", ".join(done.interrupted) or "none"
        console.print(f"{path}: recovered — writer flags cleared (were 0x{done.flags:02x}), runs marked interrupted: "
                      f"{cut}; continue the session with rig run --resume {path}", highlight=False,
                      soft_wrap=True)  # a command is never broken across lines
