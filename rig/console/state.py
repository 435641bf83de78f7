"""What the console knows of the running test, from the service's telemetry: the last status, the current run's
header, the last :data:`WINDOW_S` seconds of measured fall-line acceleration and pose, the run's detections, and the
session's faults, each with the ``plan_index`` of the run it happened in (the service's tag, else the run whose
header came last). A browser that connects gets all of it at once (:meth:`ConsoleState.hello`), then every message as it
comes."""

from __future__ import annotations

import collections
from typing import Any

WINDOW_S = 20.0
"""Seconds of live data kept for a browser that connects during a run."""

HISTORY_POINTS = 2000
"""Points of each live series kept at most (the 50 Hz acceleration over :data:`WINDOW_S` is 1,000)."""


class ConsoleState:
    """Folds the telemetry into the picture a new browser needs (module docstring)."""

    def __init__(self) -> None:
        self.status: dict[str, Any] | None = None
        self.header: dict[str, Any] | None = None
        self.session: str | None = None
        self.accel: collections.deque[tuple[float, float]] = collections.deque(maxlen=HISTORY_POINTS)
        self.pose: collections.deque[tuple[float, list[float]]] = collections.deque(maxlen=HISTORY_POINTS)
        self.detections: list[dict[str, Any]] = []
        self.faults: collections.deque[dict[str, Any]] = collections.deque(maxlen=100)

    def on_status(self, status: dict[str, Any]) -> dict[str, Any]:
        """A STATUS publication; the message for the browsers."""
        self.status = status
        return {"type": "status", **status}

    def on_live(self, frame: dict[str, Any]) -> dict[str, Any]:
        """A live frame (``rig.service.telemetry.LivePublisher``); the message for the browsers."""
        header = frame.get("header")
        if header is not None and frame.get("session") != self.session:
            self.faults.clear()  # a new session: its faults only
        if header is not None and (self.header is None or frame.get("session") != self.session
                                   or header.get("plan_index") != self.header.get("plan_index")):
            self.accel.clear()
            self.pose.clear()
            self.detections = []
        if header is not None:
            self.header, self.session = header, frame.get("session")
        accel, pose = frame.get("accel", {}), frame.get("pose", {})
        self.accel.extend(zip(accel.get("t", []), accel.get("a", []), strict=False))
        self.pose.extend(zip(pose.get("t", []), pose.get("p", []), strict=False))
        self._trim()
        self.detections.extend(frame.get("detections", []))
        current = None if self.header is None else self.header.get("plan_index")
        faults = [{**f, "plan_index": f.get("plan_index", current)} for f in frame.get("faults", [])]
        self.faults.extend(faults)
        return {"type": "live", **frame, "faults": faults}

    def _trim(self) -> None:
        for series in (self.accel, self.pose):
            while series and series[-1][0] is not None and series[0][0] is not None \
                    and series[-1][0] - series[0][0] > WINDOW_S:
                series.popleft()

    def hello(self, controls: bool) -> dict[str, Any]:
        """Everything at once, for a browser that connects (``controls``: the console can send commands)."""
        return {"type": "hello", "controls": controls, "status": self.status, "header": self.header,
                "session": self.session,
                "accel": {"t": [t for t, _ in self.accel], "a": [a for _, a in self.accel]},
                "pose": {"t": [t for t, _ in self.pose], "p": [p for _, p in self.pose]},
                "detections": self.detections, "faults": list(self.faults)}
