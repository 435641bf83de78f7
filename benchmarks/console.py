"""Benchmark: the operator's console during a 1 kHz run — frames per second delivered to one and to five browsers,
and the orchestrator's and the session logger's figures with and without the console, measured in one invocation.

One ``rig serve`` (its own process) plays the same sequence on the emulated table (1 kHz controller, MAVLink on
loopback, one Table V body) three times:

1. ``without_console``: no console process at all;
2. ``one_browser``: a console (``python -m rig.console``, its own process) subscribed to the service, one browser;
3. ``five_browsers``: the same console, five browsers.

A browser is a WebSocket client of the console (the page's own feed, ``/ws``) that reads every message, or with
``--chromium`` a headless Chromium page (Debian's ``/usr/bin/chromium`` driven by Playwright) that also draws the
uPlot plots; its frames per second are the live frames it received (or drew) between the first one and the end of
the session. Per session: the runs' underruns (the driver's report, run attribute ``underruns``), accelerometer
samples lost (gaps in each run's logged 1 kHz ``accel/0`` series: (t_last − t_first)·1000 + 1 − rows), the rows
logged, the emulator's underruns and real-time factor (from the service's log), the console's dropped frames and
the console process's CPU use over the session (percent of one core; the service's, emulator included, for the
session without the console).

Usage: ``python benchmarks/console.py [--seconds 12] [--chromium]``. Prints one JSON object.
"""

from __future__ import annotations

import argparse
import ast
import asyncio
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from protocols.signing_key import write_signing_key
from rig.console import operator_token
from rig.service import ServiceClient

SEQUENCE = """\
name = "console-bench"
angles_deg = [2]
records = [{{ record = "fema-farfield:KOBE/NIS000", window_s = [4.0, {end:g}] }}]

[drive]
settle_s = 0.5

[[bodies]]
table5 = 5
x = 0.0
y = 0.0
"""
CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def wait_for(predicate: Any, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise TimeoutError(what)
        time.sleep(0.05)


def session_figures(path: Path) -> dict[str, Any]:
    """Underruns and lost accelerometer samples of every run in the session file."""
    runs = []
    with h5py.File(path, "r", swmr=True) as h5:
        for name, run in h5["runs"].items():
            t = run["accel/0"][:, 0]
            expected = round((t[-1] - t[0]) * 1000.0) + 1 if len(t) else 0
            runs.append({"run": name, "status": run.attrs["status"], "underruns": int(run.attrs.get("underruns", -1)),
                         "accel_rows": len(t), "accel_lost": expected - len(t),
                         "largest_gap_ms": float(np.diff(t).max() * 1e3) if len(t) > 1 else None})
    return {"runs": runs, "underruns": sum(r["underruns"] for r in runs),
            "accel_lost": sum(r["accel_lost"] for r in runs)}


def emulator_figures(log: str) -> dict[str, Any]:
    """The last session's emulator counters from the service's log."""
    line = [x for x in log.splitlines() if x.startswith("rig serve: emulator: ")][-1]
    counters = ast.literal_eval(line.removeprefix("rig serve: emulator: "))
    return {"underruns": counters["underruns"], "real_time_factor": counters["timing"]["real_time_factor"],
            "accel_samples_sent": counters["link"]["accel_samples_sent"]}


class WebSocketBrowser(threading.Thread):
    """Reads the console's feed like the page does; counts live frames and when they came."""

    def __init__(self, url: str) -> None:
        super().__init__(daemon=True)
        self.url = url
        self.times: list[float] = []
        self.stop = threading.Event()
        self.connected = threading.Event()

    def run(self) -> None:
        asyncio.run(self._read())

    async def _read(self) -> None:
        import websockets

        host = self.url.removeprefix("http://").rstrip("/")
        async with websockets.connect(f"ws://{host}/ws", origin=f"http://{host}", max_size=None) as ws:
            self.connected.set()
            while not self.stop.is_set():
                try:
                    text = await asyncio.wait_for(ws.recv(), 0.2)
                except TimeoutError:
                    continue
                if text.startswith('{"type":"live"'):
                    self.times.append(time.monotonic())

    def frames(self) -> list[float]:
        return self.times


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of process ``pid`` and its waited-for children so far [s] (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return sum(int(x) for x in fields[11:15]) / os.sysconf("SC_CLK_TCK")


def fps(times: list[float], end: float) -> dict[str, Any]:
    """Live frames received: in all, and per second over the whole seconds from the first frame to the session's
    end — the median and the lowest of the seconds while the run streamed (frames come from the run's data; between
    runs only the run's header is repeated)."""
    if len(times) < 2:
        return {"frames": len(times), "fps_median": None, "fps_min_streaming": None}
    counts = np.bincount(((np.array(times) - times[0]) // 1.0).astype(int))[:-1]  # the last second is partial
    streaming = counts[counts >= 5]
    return {"frames": len(times), "fps_median": float(np.median(counts)) if len(counts) else None,
            "fps_min_streaming": int(streaming.min()) if len(streaming) else None,
            "fps_max": int(counts.max()) if len(counts) else None}


def play(client: ServiceClient, sequence: Path, log: Path) -> tuple[Path, float, dict[str, Any]]:
    session = Path(client.start(sequence, emulate=True))
    wait_for(lambda: not client.state()["active"], 600, "the session did not end")
    end = time.monotonic()
    wait_for(lambda: "rig serve: emulator: " in log.read_text().split(str(session))[-1], 60, "no emulator counters")
    return session, end, {**session_figures(session), "emulator": emulator_figures(log.read_text()),
                          "final_state": client.state()["state"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=12.0, help="record window played per session [s]")
    parser.add_argument("--chromium", action="store_true", help="browsers are headless Chromium pages")
    args = parser.parse_args()
    out: dict[str, Any] = {"unit": {"fps": "live frames received per second per browser", "accel_lost": "samples"},
                           "record_window_s": args.seconds, "load_before": os.getloadavg()}
    with tempfile.TemporaryDirectory(prefix="console-bench-") as scratch:
        root = Path(scratch)
        key_file = root / "rig.key"
        write_signing_key(key_file)
        sequence = root / "bench.toml"
        sequence.write_text(SEQUENCE.format(end=4.0 + args.seconds))
        endpoint = f"tcp/127.0.0.1:{free_port()}"
        log = root / "serve.log"
        rig = str(Path(sys.executable).with_name("rig"))
        env = {k: v for k, v in os.environ.items() if k != "SHAKETABLE_MAVLINK_KEY"}
        with log.open("w") as stderr:
            serve = subprocess.Popen([rig, "serve", "--listen", endpoint, "--sessions-dir", str(root), "--key-file",
                                      str(key_file)], stdout=subprocess.DEVNULL, stderr=stderr, env=env)
        console = None
        try:
            wait_for(lambda: "listening on" in log.read_text(), 90, "rig serve did not start")
            with ServiceClient(endpoint, key_file) as client:
                cpu0, t0 = cpu_seconds(serve.pid), time.monotonic()
                _, _, out["without_console"] = play(client, sequence, log)
                out["without_console"]["service_cpu_percent"] = round(100 * (cpu_seconds(serve.pid) - cpu0)
                                                                      / (time.monotonic() - t0), 1)
                url = f"http://127.0.0.1:{free_port()}/"
                console_log = root / "console.log"
                with console_log.open("w") as stderr:
                    console = subprocess.Popen([sys.executable, "-m", "rig.console", "--connect", endpoint, "--http",
                                                url.removeprefix("http://").rstrip("/"), "--key-file", str(key_file)],
                                               stdout=subprocess.DEVNULL, stderr=stderr, env=env)
                wait_for(lambda: "console at" in console_log.read_text(), 60, "the console did not start")
                for name, count in (("one_browser", 1), ("five_browsers", 5)):
                    cpu0, t0 = cpu_seconds(console.pid), time.monotonic()
                    out[name] = (with_chromium if args.chromium else with_websockets)(client, sequence, log, url,
                                                                                     count)
                    out[name]["console_cpu_percent"] = round(100 * (cpu_seconds(console.pid) - cpu0)
                                                             / (time.monotonic() - t0), 1)
                    out[name]["console_dropped"] = sum(b["dropped"] for b in _stats(url)["browsers"])
        finally:
            if console is not None:
                console.send_signal(signal.SIGTERM)
                console.wait(30)
            serve.send_signal(signal.SIGTERM)
            serve.wait(120)
    out["token_check"] = len(operator_token(b"\1" * 32)) == 64
    out["load_after"] = os.getloadavg()
    print(json.dumps(out, indent=1))


def _stats(url: str) -> dict[str, Any]:
    import urllib.request

    with urllib.request.urlopen(f"{url}api/state", timeout=10) as response:
        return json.loads(response.read())["stats"]


def with_websockets(client: ServiceClient, sequence: Path, log: Path, url: str, count: int) -> dict[str, Any]:
    browsers = [WebSocketBrowser(url) for _ in range(count)]
    for browser in browsers:
        browser.start()
        browser.connected.wait(30)
    try:
        _, end, figures = play(client, sequence, log)
        per_browser = [fps(b.frames(), end) for b in browsers]
    finally:
        for browser in browsers:
            browser.stop.set()
            browser.join(5)
    return {**figures, "browsers": per_browser, "kind": "websocket"}


def with_chromium(client: ServiceClient, sequence: Path, log: Path, url: str, count: int) -> dict[str, Any]:
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as profile, sync_playwright() as playwright:
        context = playwright.chromium.launch_persistent_context(profile, executable_path=str(CHROMIUM),
                                                                headless=True, args=CHROMIUM_ARGS,
                                                                viewport={"width": 1600, "height": 900})
        pages = [context.new_page() for _ in range(count)]
        for page in pages:
            page.goto(url)
            page.wait_for_function("window.consoleStats && window.consoleStats.hello >= 1")
        before = [page.evaluate("[window.consoleStats.frames, window.consoleStats.draws]") for page in pages]
        t0 = time.monotonic()
        _, end, figures = play(client, sequence, log)
        after = [page.evaluate("[window.consoleStats.frames, window.consoleStats.draws]") for page in pages]
        context.close()
    seconds = end - t0
    return {**figures, "kind": "chromium", "browsers": [
        {"frames": a[0] - b[0], "draws": a[1] - b[1], "fps_over_session": round((a[0] - b[0]) / seconds, 2),
         "draws_per_s_over_session": round((a[1] - b[1]) / seconds, 2)} for a, b in zip(after, before, strict=True)]}


if __name__ == "__main__":
    main()
