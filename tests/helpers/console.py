"""The console's tests: a stand-in for the rig service that records what it is asked, the headers of a page of
the console's own origin, and how Debian's Chromium is started headless."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rig.service import ServiceError

HOST = "127.0.0.1:8080"
SAME = {"Host": HOST, "Origin": f"http://{HOST}", "Content-Type": "application/json"}


class RecordingControls:
    """Stands for the rig service: records what it was asked; refuses ``refuse`` commands as the service does."""

    def __init__(self, refuse: tuple[str, ...] = ()) -> None:
        self.calls: list[tuple[str, str]] = []
        self.refusals: list[tuple[str, str, str]] = []
        self.args: list[dict[str, Any]] = []
        self.refuse = refuse

    def command(self, command: str, source: str, args: dict[str, Any]) -> dict[str, Any]:
        self.calls.append((command, source))
        self.args.append(args)
        if command in self.refuse:
            raise ServiceError(f"cannot {command}: no session is running")
        return {"ok": True, "state": "running", "message": f"{command} requested"}

    def refused(self, command: str, source: str, reason: str) -> None:
        self.refusals.append((command, source, reason))


CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]
