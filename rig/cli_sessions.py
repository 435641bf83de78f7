"""``rig sessions list|show``: the session files of a directory, and one session's runs (also while it is written)."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer
from rich import box
from rich.table import Table

from rig.session import SessionError, list_sessions, read_session


def run_rows(session: dict[str, Any]) -> list[dict[str, Any]]:
    """One summary per run: name, plan index, record, angle [deg], scale factor, status, accelerometer samples of
    each sensor and their span [s], overturns ``body:direction`` (operator's marked ``*``)."""
    rows = []
    for run in session["runs"]:
        accel = run.get("accel", {})
        spans = [float(a[-1, 0] - a[0, 0]) for a in accel.values() if len(a)]
        detections = " ".join(f"{d['body_id']}:{d['direction']:+d}{'*' if d['source'] == 'operator' else ''}"
                              for d in run.get("detections", []))
        rows.append({"run": run["name"], "plan": run["plan_index"] + 1, "record": run["record"],
                     "angle_deg": run["angle_deg"], "scale_factor": run["scale_factor"], "status": run["status"],
                     "samples": sum(len(a) for a in accel.values()), "seconds": max(spans, default=0.0),
                     "overturns": detections or "-"})
    return rows


def print_session(path: Path, console: Any) -> None:
    """The session's header and a table of its runs."""
    session = read_session(path)
    sequence = session.get("sequence") or {}
    console.print(f"[bold]{path}[/]  sequence {sequence.get('name', '?')!r}, created {session['created']}, "
                  f"software {session['software_version']}")
    table = Table(box=box.SIMPLE_HEAD)
    for name, justify in (("run", "left"), ("plan", "right"), ("record", "left"), ("β [°]", "right"),
                          ("scale", "right"), ("status", "left"), ("accel samples", "right"), ("span [s]", "right"),
                          ("overturns body:dir", "left")):
        table.add_column(name, justify=justify)  # type: ignore[arg-type]
    for row in run_rows(session):
        scale = row["scale_factor"]
        table.add_row(row["run"], str(row["plan"]), row["record"], f"{row['angle_deg']:g}",
                      "-" if scale is None or math.isnan(scale) else f"{scale:.3f}", row["status"],
                      str(row["samples"]), f"{row['seconds']:.1f}", row["overturns"])
    console.print(table)


def register(app: typer.Typer, fail: Callable[[str], Any], console: Any) -> None:
    """Add ``rig sessions list|show``."""
    sessions = typer.Typer(help="Session files: list a directory's, show one's runs.", no_args_is_help=True)
    app.add_typer(sessions, name="sessions")

    @sessions.command("list")
    def list_cmd(directory: Annotated[Path, typer.Argument(help="where the session files are")] = Path(".")) -> None:
        """The session files in DIRECTORY: created, runs and their statuses, whether one is being written."""
        try:
            found = list_sessions(directory)
        except (SessionError, OSError) as exc:
            fail(str(exc))
        table = Table(box=box.SIMPLE_HEAD)
        for name in ("file", "created", "runs", "statuses", "writing"):
            table.add_column(name)
        for s in found:
            statuses = ", ".join(f"{k} {v}" for k, v in sorted(s["statuses"].items())) if isinstance(
                s["statuses"], dict) else str(s["statuses"])
            table.add_row(Path(s["path"]).name, s["created"], str(s["runs"]), statuses,
                          "yes" if s["open_for_write"] else "")
        console.print(table)

    @sessions.command("show")
    def show_cmd(path: Annotated[Path, typer.Argument(metavar="SESSION.h5")]) -> None:
        """One session's runs: record, angle, scale factor, status, samples, overturns."""
        try:
            print_session(path, console)
        except (SessionError, OSError) as exc:
            fail(str(exc))
