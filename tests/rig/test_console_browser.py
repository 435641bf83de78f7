"""The operator console in a real browser: ``rig serve --http`` in its own process (the console its child), the
page opened in headless Chromium (Debian's, driven by Playwright; skipped when it is not installed) while the
emulated table plays the service tests' tiny sequence. The plots update, a detection appears on the plate, the page
is read-only without the operator token, pause and resume from the page work with it, a foreign page's control
request is refused, and every control request is in the session file's events with its source.

``RIG_CONSOLE_SCREENSHOT=docs/console.png`` also saves the screenshot the README shows."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import h5py
import pytest

from protocols.signing_key import write_signing_key
from rig.console import operator_token
from rig.service import ServiceClient
from tests.helpers.console import CHROMIUM, CHROMIUM_ARGS
from tests.helpers.processes import free_port, serve_command
from tests.helpers.sequences import TINY

pytestmark = [pytest.mark.integration, pytest.mark.skipif(not CHROMIUM.exists(),
                                reason="Debian's chromium is not installed (apt-get install chromium)")]


class ServiceWithConsole:
    """``rig serve --http``: the service, its console's URL, the key file and the log."""

    def __init__(self, root: Path) -> None:
        self.sessions = root / "sessions"
        self.key_file = root / "rig.key"
        write_signing_key(self.key_file)
        self.endpoint = f"tcp/127.0.0.1:{free_port()}"
        self.url = f"http://127.0.0.1:{free_port()}/"
        self.log = root / "serve.log"
        env = {k: v for k, v in os.environ.items() if k != "SHAKETABLE_MAVLINK_KEY"}
        with self.log.open("w") as log:
            self.proc = subprocess.Popen([*serve_command(), "--listen", self.endpoint, "--sessions-dir",
                                          str(self.sessions), "--key-file", str(self.key_file), "--http",
                                          self.url.removeprefix("http://").rstrip("/")],
                                         stdout=subprocess.DEVNULL, stderr=log, env=env, cwd=root)
        wait_until(lambda: "listening on" in self.log.read_text() and self.proc.poll() is None, 90,
                   lambda: f"rig serve did not start: {self.log.read_text()}")
        assert f"console at {self.url}" in self.log.read_text()

    def stop(self) -> str:
        self.proc.send_signal(signal.SIGTERM)
        try:
            self.proc.wait(60)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            raise
        return self.log.read_text()


def wait_until(predicate: Callable[[], Any], timeout: float, why: Callable[[], str] = lambda: "timed out") -> Any:
    deadline = time.monotonic() + timeout
    while not (value := predicate()):
        assert time.monotonic() < deadline, why()
        time.sleep(0.05)
    return value


@pytest.fixture
def service(tmp_path: Path) -> Iterator[ServiceWithConsole]:
    running = ServiceWithConsole(tmp_path)
    try:
        yield running
    finally:
        log = running.stop()
    assert running.proc.returncode == 0, log


@pytest.fixture
def browser(tmp_path: Path) -> Iterator[Any]:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        context = playwright.chromium.launch_persistent_context(
            str(tmp_path / "profile"), executable_path=str(CHROMIUM), headless=True, args=CHROMIUM_ARGS,
            viewport={"width": 1600, "height": 900})
        try:
            yield context
        finally:
            context.close()


@pytest.mark.slow  # a real browser over a whole session at 1x; test_console.py checks the page's server quickly
def test_the_console_follows_a_session_and_controls_it(service: ServiceWithConsole, browser: Any,
                                                       tmp_path: Path) -> None:
    page = browser.new_page()
    page.goto(service.url)
    page.wait_for_function("() => window.consoleStats && window.consoleStats.hello >= 1")
    assert page.get_attribute("#pause", "disabled") is not None  # read-only until the token is given
    assert page.is_visible("#estop")

    sequence = tmp_path / "tiny.toml"
    sequence.write_text(TINY)
    with ServiceClient(service.endpoint, service.key_file) as client:
        session = Path(client.start(sequence, emulate=True))

        # the plots update: live frames arrive and are drawn
        page.wait_for_function("() => window.consoleStats.draws >= 5", timeout=60_000)
        before = page.evaluate("[window.consoleStats.frames, window.consoleStats.draws]")
        page.wait_for_timeout(1000)
        after = page.evaluate("[window.consoleStats.frames, window.consoleStats.draws]")
        assert after[0] > before[0] and after[1] > before[1], (before, after)
        assert page.get_attribute("#state", "data-state") == "running"
        assert page.inner_text("#run-record").startswith("fema-nearfield:NORTHR/RRS_032")

        # without the token the page's controls are refused; a foreign page's are refused before the token
        refused = page.evaluate("""async () => { const r = await fetch('/api/control/pause', {method: 'POST',
            headers: {'Content-Type': 'application/json'}, body: '{}'});
            return [r.status, (await r.json()).message]; }""")
        assert refused[0] == 403 and "token" in refused[1]
        token = operator_token(bytes.fromhex(service.key_file.read_text().strip()))
        foreign = browser.new_page()
        foreign.goto("data:text/html,<p>another site</p>")
        outcome = foreign.evaluate(f"""async () => {{ try {{ const r = await fetch('{service.url}api/control/pause',
            {{method: 'POST', headers: {{'Content-Type': 'application/json', 'X-Operator-Token': '{token}'}},
              body: '{{}}'}}); return 'answered ' + r.status; }} catch (e) {{ return 'blocked'; }} }}""")
        assert outcome == "blocked"  # no CORS: the preflight fails, the request never reaches the control
        foreign.close()
        assert client.state()["state"] == "running"

        # the operator gives the token once; pause at the end of the record
        page.fill("#token", token)
        page.click("#unlock")
        page.wait_for_function("() => !document.getElementById('pause').disabled")
        assert "unlocked" in page.inner_text("#control-mode")
        page.click("#pause")
        page.wait_for_function("() => document.getElementById('state').dataset.state === 'paused'",
                               timeout=60_000)
        assert client.state()["state"] == "paused"
        # the first record overturned the body (the emulator's specimen): the detection is on the plate
        page.wait_for_function("() => window.consoleStats.detections >= 1", timeout=10_000)
        assert "fell to the" in page.inner_text("#detections")

        page.click("#resume")
        page.wait_for_function("() => document.getElementById('state').dataset.state === 'running'",
                               timeout=60_000)
        page.wait_for_function("() => window.consoleStats.planIndex === 1 && window.consoleStats.lastT > 4.5",
                               timeout=60_000)  # most of the second record
        shown = page.evaluate("[document.getElementById('table-state').textContent, "
                              "JSON.stringify(window.consoleStats), document.getElementById('message').textContent]")
        assert shown[0] == "streaming", shown  # the status is current: the statuses are never the frames dropped
        screenshot = tmp_path / "console.png"
        page.screenshot(path=str(screenshot))
        assert screenshot.stat().st_size > 10_000
        if os.environ.get("RIG_CONSOLE_SCREENSHOT"):
            Path(os.environ["RIG_CONSOLE_SCREENSHOT"]).write_bytes(screenshot.read_bytes())
        wait_until(lambda: not client.state()["active"], 120)
    page.wait_for_function("() => ['done', 'faulted'].includes(document.getElementById('state').dataset.state)")
    assert page.is_visible("#report")

    with h5py.File(session, "r", swmr=True) as h5:
        events = [text.decode() for run in h5["runs"].values() for _, text in run["events"][:]]
    controls = [e for e in events if " control " in e]
    assert len(controls) == 2, events
    # the source as the console's signed request names it: the browser session that unlocked the controls
    assert " control pause from console browser session 1, unlocked " in controls[0]
    assert controls[0].endswith("accepted") and " from 127.0.0.1 (HeadlessChrome/" in controls[0]
    assert "(signed: rig key holder " in controls[0]
    assert " control resume from console browser session 1, unlocked " in controls[1]
