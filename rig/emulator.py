"""The emulated table as a separate process (``python -m sim_table``), started and stopped from the lab side.

`rig` never imports `sim_table` (docs/architecture.md §1: the emulator stands where the table's own controller would):
it runs it, as ``rig run --emulate``, the demo, the tests and the benchmarks do. The emulator prints
``sim_table: listening on URL`` on stderr once its endpoint is open (port 0 resolved), and its counters as one
JSON object on stdout when it stops (SIGINT).

The emulator runs in a process group of its own, so the operator's Ctrl-C at the terminal reaches ``rig`` alone
(``rig run`` pauses on it; the table must not die under the session), and with ``--exit-with-parent``: it ends when
the process that started it ends, even by ``kill -9``, so no orphaned emulator keeps its port.
"""

from __future__ import annotations

import json
import math
import os
import re
import select
import signal
import subprocess
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rig.sequence import PlacedBody

_LISTENING = re.compile(r"listening on (\S+)")


def specimen_flags(bodies: Iterable[PlacedBody]) -> list[str]:
    """The emulator's ``--body`` flags for a sequence's bodies, in their order (the emulator numbers its bodies
    0, 1, … in this order: the orchestrator maps those back to the bodies' ids)."""
    flags = []
    for placed in bodies:
        body = placed.body
        options = [f"depth={placed.depth!r}", f"mu={placed.friction!r}"]
        if body.mass is not None:
            options.append(f"mass={body.mass!r}")
        if placed.restitution is not None:
            options.append(f"restitution={placed.restitution!r}")
        if not body.centred:
            options.append("cg={!r},{!r}".format(*body.cg))
        flags += ["--body", f"{body.b!r}x{body.h!r}@{placed.x!r},{placed.y!r};" + ";".join(options)]
    return flags


def parse_speed(text: str | float) -> float:
    """A ``--speed`` option: controller time per real time (a factor > 0), or ``max``: virtual time (math.inf),
    the emulator as fast as it computes (``docs/table-controller.md``); a number passes as it is (the option's
    default). ValueError names what is wrong."""
    if isinstance(text, str) and text.strip().lower() == "max":
        return math.inf
    try:
        speed = float(text)
    except ValueError:
        speed = math.nan
    if not (math.isfinite(speed) and speed > 0):
        raise ValueError(f"--speed: expected a factor > 0 or max, got {text!r}")
    return speed


def speed_flags(speed: float) -> list[str]:
    """The emulator's ``--speed`` flag for ``speed`` (math.inf: ``max``)."""
    return ["--speed", "max" if math.isinf(speed) else f"{speed:g}"]


class EmulatorError(RuntimeError):
    """The emulator did not start, or did not stop cleanly; the message carries what it printed."""


@dataclass
class EmulatorProcess:
    """A running emulator: its process and the URL a `drivers.controller.open_table` connects to."""

    proc: subprocess.Popen[str]
    url: str

    @classmethod
    def start(cls, listen: str = "mavlink://127.0.0.1:0", *flags: str, key_file: Path | None = None,
              env: dict[str, str] | None = None) -> EmulatorProcess:
        """Start ``python -m sim_table --listen LISTEN FLAGS…`` and wait until it listens.

        ``key_file`` is the signing key (else ``$SHAKETABLE_MAVLINK_KEY`` of ``env``/this process);
        ``env`` adds to this process's environment.
        """
        cmd = [sys.executable, "-m", "sim_table", "--listen", listen, "--exit-with-parent", *flags]
        if key_file is not None:
            cmd += ["--key-file", str(key_file)]
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                env={**os.environ, **(env or {})}, start_new_session=True)
        assert proc.stderr is not None
        seen = []
        for line in proc.stderr:
            seen.append(line)
            found = _LISTENING.search(line)
            if found:
                return cls(proc, found.group(1))
        proc.wait()
        raise EmulatorError(f"the emulator did not start (exit {proc.returncode}): {''.join(seen).strip()}")

    @property
    def exit_code(self) -> int | None:
        """None while the emulator runs, else its exit status (negative: killed by that signal)."""
        return self.proc.poll()

    def stop(self, timeout: float = 20.0) -> dict[str, Any]:
        """SIGINT, wait at most ``timeout`` s, and return the counters it printed."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            out, err = self.proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            out, err = self.proc.communicate()
            raise EmulatorError(f"the emulator did not stop within {timeout:g} s: {err.strip()}") from None
        if self.proc.returncode != 0:
            raise EmulatorError(f"the emulator exited with {self.proc.returncode}: {err.strip()}")
        return json.loads(out)

    def rest(self, timeout: float = 20.0) -> dict[str, Any]:
        """Bring the table back to its power-up state (SIGUSR1: at home, idle, no owner, every counter zero;
        ``sim_table.process.Emulator.rest``, MAVLink and zenoh) and return the counters up to then, as
        :meth:`stop` would have; waits at most ``timeout`` [s]. For tests sharing one emulator."""
        assert self.proc.stdout is not None
        if self.proc.poll() is not None:
            raise EmulatorError(f"the emulator has exited ({self.proc.returncode}): nothing to bring to rest")
        self.proc.send_signal(signal.SIGUSR1)
        ready, _, _ = select.select([self.proc.stdout], [], [], timeout)
        line = self.proc.stdout.readline() if ready else ""
        if not line:
            raise EmulatorError(f"the emulator did not come back to rest within {timeout:g} s "
                                f"(exit {self.proc.poll()})")
        return json.loads(line)

    def __enter__(self) -> EmulatorProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.proc.poll() is None:
            self.stop()


def counter_rows(counters: dict[str, Any]) -> list[tuple[str, str]]:
    """The emulator's counters (its exit JSON object) as ``(name, value)`` rows for a table: nested objects
    (``link``, ``timing``, ``faults_raised``) flattened to ``link.packets_sent`` etc., numbers as they are (floats to
    4 significant digits), lists joined (``faults``) or counted (``overturns``: ``N``, each shown by
    :func:`overturn_rows`)."""
    rows: list[tuple[str, str]] = []

    def add(name: str, value: Any) -> None:
        if isinstance(value, dict):
            if not value:
                rows.append((name, "-"))
            for key, sub in value.items():
                add(f"{name}.{key}", sub)
        elif isinstance(value, list):
            is_records = bool(value) and all(isinstance(v, dict) for v in value)
            rows.append((name, str(len(value)) if is_records else (", ".join(map(str, value)) or "-")))
        elif isinstance(value, float):
            rows.append((name, f"{value:.4g}"))
        else:
            rows.append((name, "-" if value is None else str(value)))

    for key, value in counters.items():
        add(key, value)
    return rows


def overturn_rows(counters: dict[str, Any]) -> list[tuple[str, str, str, str, str]]:
    """The emulator's overturns as rows: event id, body id, direction (+1 towards the low side), controller time
    [s], plate tilt [°]."""
    return [(str(o["event_id"]), str(o["body_id"]), f"{o['direction']:+d}", f"{o['t']:.3f}",
             f"{math.degrees(o['tilt']):.2f}") for o in counters.get("overturns", [])]


def counters_summary(counters: dict[str, Any]) -> str:
    """One line of what matters in the emulator's counters (for a log): state, faults, underruns, refused
    commands, stops, overturns."""
    faults = ", ".join(counters.get("faults", [])) or "none"
    return (f"state {counters.get('state', '?')}, faults {faults}, underruns {counters.get('underruns', 0)}, "
            f"refused commands {counters.get('refused_commands', 0)}, stops {counters.get('stops', 0)}, "
            f"watchdog stops {counters.get('watchdog_stops', 0)}, overturns {len(counters.get('overturns', []))}")
