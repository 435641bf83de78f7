"""The link between the lab host and the table controller: how far ahead setpoints go, how much the controller
buffers, and how soon each end declares the other lost (the rig TOML's ``[controller]`` section).

A lab host is a shared PC: it writes files, draws plots, runs the console, and waits for a person. These settings
make a stall of the host shorter than the **lead** harmless (the controller plays what it holds), while a host or
link that is really gone is noticed within a stated bound:

- ``lead_s`` (default 1.0 s): setpoint chunks are sent this far ahead of their first sample. A host stall shorter
  than the lead never starves the table.
- ``buffer_s`` (default 4.0 s): what the controller's setpoint buffer holds (reported in every status as samples);
  it must exceed the lead by at least :data:`BUFFER_MARGIN_S` (the chunks sent twice, the clock's jitter).
- ``watchdog_s`` (default 1.0 s): the controller stops the table (controlled stop, home, ``faulted``) after this
  long without a host heartbeat, or while streaming without a setpoint chunk. It is at least the lead, so that a
  host stall the buffer absorbs does not trip it; then the table stops within ``watchdog_s`` of the host's death.
- ``link_timeout_s`` (default 0.5 s): the host declares the link lost after this long without a status (the
  controller reports at 50 Hz), and says so within a second.

The controller's own values are the controller's (the emulator reads them from the same file); the host's are
written into each session file beside the capacity the controller reported.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

BUFFER_MARGIN_S = 0.1
"""The buffer must hold at least this much more than the lead [s]."""

RANGES: dict[str, tuple[float, float]] = {
    "lead_s": (0.02, 30.0),
    "buffer_s": (0.1, 120.0),
    "watchdog_s": (0.02, 10.0),
    "link_timeout_s": (0.1, 10.0),
}
"""Accepted range [s] of every ``[controller]`` key (inclusive)."""


@dataclass(frozen=True)
class LinkSettings:
    """The ``[controller]`` section (module docstring); all in seconds."""

    lead_s: float = 1.0
    buffer_s: float = 4.0
    watchdog_s: float = 1.0
    link_timeout_s: float = 0.5

    def __post_init__(self) -> None:
        problem = self.problem()
        if problem is not None:
            raise ValueError(f"{problem[0]}: {problem[1]}")

    def problem(self) -> tuple[str, str] | None:
        """(key, what is wrong) of the first bad value, else None."""
        for key, (low, high) in RANGES.items():
            value = getattr(self, key)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and low <= value <= high):
                return key, f"must be a number of seconds in [{low:g}, {high:g}], got {value!r}"
        if self.buffer_s < self.lead_s + BUFFER_MARGIN_S:
            return "buffer_s", (f"the buffer ({self.buffer_s:g} s) must hold the lead ({self.lead_s:g} s) and "
                                f"{BUFFER_MARGIN_S:g} s more: raise buffer_s or lower lead_s")
        if self.watchdog_s < self.lead_s:
            return "watchdog_s", (f"the watchdog ({self.watchdog_s:g} s) must be at least the lead "
                                  f"({self.lead_s:g} s): else a host stall the buffer absorbs stops the table")
        return None

    def buffer_capacity(self, rate_hz: float) -> int:
        """The buffer's capacity in setpoint samples at ``rate_hz``."""
        return math.ceil(self.buffer_s * rate_hz)

    def to_dict(self) -> dict[str, float]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> LinkSettings:
        """From the section's keys (unknown keys are the caller's to refuse); ValueError names the key."""
        return cls(**{key: data[key] for key in RANGES if key in data})
