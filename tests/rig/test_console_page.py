"""The console's page in headless Chromium (Debian's, driven by Playwright; skipped when it is not installed), fed by
the test instead of a rig service: the console's real server (uvicorn, the connection guard) in a thread, its
telemetry delivered as the service's would be, its controls recorded. Hostile telemetry is shown as text and runs
no script; the operator token is kept nowhere a page script can read; the pose axes keep a minimum span at rest;
faults stay with their run; buttons that would do nothing are disabled; a queued session is started and an operator
prompt answered from the page."""

from __future__ import annotations

import asyncio
import secrets
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

from rig.console import Console, operator_token
from rig.console.server import allowed_hosts, console_server
from tests.helpers.console import CHROMIUM, CHROMIUM_ARGS, RecordingControls
from tests.helpers.processes import free_port

pytestmark = [pytest.mark.integration, pytest.mark.skipif(not CHROMIUM.exists(),
                                reason="Debian's chromium is not installed (apt-get install chromium)")]

SCRIPT = "<img src=x onerror=\"window.pwned=(window.pwned||[]).concat('{}')\">"
"""Markup that runs a script when a field is rendered as HTML; the argument names the field."""


class FedConsole:
    """The console served on a free loopback port, its telemetry given by :meth:`deliver`."""

    def __init__(self) -> None:
        self.controls = RecordingControls()
        self.token = operator_token(secrets.token_bytes(32))
        port = free_port()
        self.console = Console(self.controls, self.token, allowed_hosts=allowed_hosts("127.0.0.1", port))
        self.url = f"http://127.0.0.1:{port}/"
        self.loop: asyncio.AbstractEventLoop | None = None
        self.server = console_server(self.console, "127.0.0.1", port, on_startup=self._started)
        self.thread = threading.Thread(target=lambda: asyncio.run(self.server.serve()), daemon=True)
        self.thread.start()
        deadline = time.monotonic() + 30
        while not self.server.started:
            assert time.monotonic() < deadline and self.thread.is_alive(), "the console did not start"
            time.sleep(0.02)

    def _started(self, loop: asyncio.AbstractEventLoop) -> None:
        self.loop = loop

    def deliver(self, kind: str, body: dict[str, Any]) -> None:
        assert self.loop is not None
        self.loop.call_soon_threadsafe(self.console.deliver, kind, {"t_ns": time.time_ns(), "seq": 1, **body})

    def status(self, state: str, active: bool = True, **fields: Any) -> None:
        progress = {"run": None, "runs_done": 0, "runs_total": 2, "samples_sent": 0, "samples_total": 0,
                    "table_state": "armed", "peak_accel": 0.0, "detections": 0, "message": "", "outcomes": {}}
        progress.update(fields.pop("progress", {}))
        self.deliver("status", {"state": state, "message": fields.pop("message", state), "session": "s.h5",
                                "active": active, "progress": progress, "queue": [], "prompt": None, **fields})

    def close(self) -> None:
        self.server.should_exit = True
        self.thread.join(10)


def header(plan_index: int, **extra: Any) -> dict[str, Any]:
    return {"plan_index": plan_index, "record": "fema:NORTHR/RRS_032", "angle_deg": 0.0, "scale_factor": 0.5,
            "duration_s": 6.0, "rate": 1000.0, "table_seconds_after": 0.0,
            "plan": [{"plan_index": 0, "record": "r1", "angle_deg": 0.0},
                     {"plan_index": 1, "record": "r2", "angle_deg": 0.0}],
            "bodies": [{"body_id": 1, "name": "A", "b": 0.1, "h": 0.5, "depth": 0.1, "x": -0.2, "y": 0.0},
                       {"body_id": 2, "name": "B", "b": 0.1, "h": 0.5, "depth": 0.1, "x": 0.2, "y": 0.0}],
            "commanded": {"t": [0.0, 6.0], "a": [0.0, 0.0]},
            "limits": {"surge_m": 0.25, "sway_m": 0.25, "heave_m": 0.18, "tilt_deg": 10.0}, **extra}


def live(plan_index: int | None = None, **fields: Any) -> dict[str, Any]:
    frame = {"state": "live", "session": "s.h5", "accel": {"t": [], "a": []}, "pose": {"t": [], "p": []},
             "detections": [], "faults": []}
    if plan_index is not None:
        frame["header"] = header(plan_index)
    frame.update(fields)
    return frame


@pytest.fixture
def fed() -> Iterator[FedConsole]:
    console = FedConsole()
    try:
        yield console
    finally:
        console.close()


@pytest.fixture
def page(fed: FedConsole, tmp_path: Any) -> Iterator[Any]:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        context = playwright.chromium.launch_persistent_context(
            str(tmp_path / "profile"), executable_path=str(CHROMIUM), headless=True, args=CHROMIUM_ARGS,
            viewport={"width": 1600, "height": 900})
        try:
            opened = context.new_page()
            opened.goto(fed.url)
            opened.wait_for_function("() => window.consoleStats && window.consoleStats.hello >= 1")
            yield opened
        finally:
            context.close()


def unlock(page: Any, token: str) -> None:
    page.fill("#token", token)
    page.click("#unlock")
    page.wait_for_function("() => document.getElementById('control-mode').textContent.includes('unlocked')")


def test_hostile_telemetry_is_shown_as_text_and_runs_no_script(fed: FedConsole, page: Any) -> None:
    hostile = header(0, record=SCRIPT.format("record"),
                     plan=[{"plan_index": 0, "record": SCRIPT.format("plan record"), "angle_deg": 0.0}],
                     bodies=[{"body_id": SCRIPT.format("body id"), "name": SCRIPT.format("body name"), "b": 0.1,
                              "h": 0.5, "depth": 0.1, "x": 0.0, "y": 0.0}])
    fed.deliver("live", live(header=hostile, faults=[{"t": 1.0, "name": SCRIPT.format("fault name"),
                                                      "detail": SCRIPT.format("fault detail")}],
                             detections=[{"t": 1.0, "body_id": SCRIPT.format("detection"), "direction": 1}]))
    fed.status("waiting for the operator", message=SCRIPT.format("message"),
               progress={"outcomes": {"0": SCRIPT.format("outcome")}, "run": {"plan_index": 0, "angle_deg": 0.0}},
               queue=[{"id": 1, "name": SCRIPT.format("queue name"), "emulate": True, "attended": True}],
               prompt={"id": 1, "kind": "which_fell", "text": SCRIPT.format("prompt"),
                       "bodies": [{"body_id": 1, "name": SCRIPT.format("prompt body")}]})
    page.wait_for_function("() => document.getElementById('runs').textContent.includes('outcome')")
    page.wait_for_timeout(500)  # time for any injected image to fail to load and run its handler
    assert page.evaluate("window.pwned || []") == []
    assert SCRIPT.format("outcome") in page.inner_text("#runs")  # shown as the text it is
    assert SCRIPT.format("queue name") in page.inner_text("#queue")
    assert SCRIPT.format("fault detail") in page.inner_text("#faults")
    assert page.evaluate("document.querySelectorAll('#runs img, #queue img, #faults img, #plate img, "
                         "#prompt-box img, #detections img').length") == 0


def test_the_operator_token_is_kept_where_no_page_script_can_read_it(fed: FedConsole, page: Any) -> None:
    unlock(page, fed.token)
    fed.status("running", progress={"run": {"plan_index": 0, "angle_deg": 0.0}})
    page.wait_for_function("() => !document.getElementById('pause').disabled")
    stored = page.evaluate("JSON.stringify([document.cookie, Object.entries(localStorage), "
                           "Object.entries(sessionStorage)])")
    assert fed.token not in stored and stored == '["",[],[]]'
    page.click("#pause")
    page.wait_for_function("() => document.getElementById('control-reply').textContent"
                           ".includes('pause requested')")
    assert fed.controls.calls[-1][0] == "pause"
    assert fed.controls.calls[-1][1].startswith("console browser session 1, unlocked ")
    assert "HeadlessChrome" in fed.controls.calls[-1][1]
    page.reload()  # the browser session survives a reload without the token being stored
    page.wait_for_function("() => document.getElementById('control-mode').textContent.includes('unlocked')")
    # a script that knows neither the CSRF token nor the operator token is refused, cookie or not
    refused = page.evaluate("""async () => (await fetch('/api/control/abort', {method: 'POST',
        headers: {'Content-Type': 'application/json'}, body: '{}'})).status""")
    assert refused == 403 and [c for c, _ in fed.controls.calls] == ["pause"]


def test_the_pose_axes_keep_a_minimum_span_at_rest(fed: FedConsole, page: Any) -> None:
    t = [i * 0.02 for i in range(200)]
    noise = [[1e-7 * (-1) ** i, 0.0, 0.0, 1e-6 * (-1) ** i, 2e-6, 0.0] for i in range(200)]  # β = 0, at rest
    fed.deliver("live", live(0, pose={"t": t, "p": noise}))
    page.wait_for_function("() => window.consoleStats.draws >= 1 && window.consolePlots.pose.scales.deg.max !== null"
                           " && window.consolePlots.pose.scales.deg.max !== undefined")
    deg = page.evaluate("[window.consolePlots.pose.scales.deg.min, window.consolePlots.pose.scales.deg.max]")
    mm = page.evaluate("[window.consolePlots.pose.scales.mm.min, window.consolePlots.pose.scales.mm.max]")
    assert deg[1] - deg[0] >= 2 * 0.02 * 10.0 * 0.999, deg  # ±2 % of the 10° tilt limit at least
    assert mm[1] - mm[0] >= 2 * 0.02 * 250.0 * 0.999, mm  # ±2 % of the 250 mm stroke at least
    big = [[0.0, 0.0, 0.0, 0.0, 0.1 * (i % 2), 0.0] for i in range(200)]  # 5.7° of pitch: the data's own range
    fed.deliver("live", live(pose={"t": [x + 4.0 for x in t], "p": big}))
    page.wait_for_function("() => window.consolePlots.pose.scales.deg.max > 5.7")


def test_faults_stay_with_their_run(fed: FedConsole, page: Any) -> None:
    fed.deliver("live", live(0))
    fed.deliver("live", live(faults=[{"t": 2.5, "name": "UNDERRUN", "detail": "buffer empty"}]))
    fed.deliver("live", live(1))
    fed.status("running", progress={"run": {"plan_index": 1, "angle_deg": 0.0}, "outcomes": {"0": "completed"}})
    page.wait_for_function("() => window.consoleStats.planIndex === 1")
    page.wait_for_function("() => document.querySelectorAll('#runs tr').length === 2")
    assert page.inner_text("#faults").startswith("run 1 · 2.50 s · UNDERRUN")
    cells = page.evaluate("[...document.querySelectorAll('#runs tr')].map((r) => r.lastElementChild.textContent)")
    assert cells == ["1", ""]  # one fault in run 1, none in run 2


@pytest.mark.parametrize(("state", "active", "enabled"), [
    ("running", True, {"pause", "abort"}),
    ("paused", True, {"resume", "abort"}),
    ("stopping", True, set()),
    ("done", False, set()),
    ("idle", False, set()),
])
def test_buttons_that_would_do_nothing_are_disabled(fed: FedConsole, page: Any, state: str, active: bool,
                                                    enabled: set[str]) -> None:
    unlock(page, fed.token)
    fed.status(state, active=active)
    page.wait_for_function(f"() => document.getElementById('state').dataset.state === '{state}'")
    shown = page.evaluate("['pause', 'resume', 'abort'].filter((id) => !document.getElementById(id).disabled)")
    assert set(shown) == enabled
    assert page.is_enabled("#estop")  # the emergency stop is never disabled


def test_a_queued_session_is_started_and_a_prompt_answered_from_the_page(fed: FedConsole, page: Any) -> None:
    fed.status("idle", active=False, queue=[{"id": 3, "name": "tiny.toml", "emulate": True, "attended": True}])
    page.wait_for_selector("#queue button.start")
    assert page.is_disabled("#queue button.start")  # locked: read-only
    unlock(page, fed.token)
    page.wait_for_function("() => !document.querySelector('#queue button.start').disabled")
    page.click("#queue button.start")
    page.wait_for_function("() => document.getElementById('control-reply').textContent"
                           ".includes('start requested')")
    assert fed.controls.calls[-1][0] == "start" and fed.controls.args[-1] == {"queued": 3}

    fed.deliver("live", live(0))
    fed.status("waiting for the operator", prompt={"id": 5, "kind": "which_fell", "text": "which bodies fell?",
                                                    "bodies": [{"body_id": 1, "name": "A"},
                                                               {"body_id": 2, "name": "B"}]})
    page.wait_for_selector("#fell-2")
    assert page.inner_text("#prompt") == "which bodies fell?"
    page.select_option("#fell-2", "-1")
    page.click("#answer-done")
    page.wait_for_function("() => document.getElementById('control-reply').textContent"
                           ".includes('answer requested')")
    assert fed.controls.calls[-1][0] == "answer"
    assert fed.controls.args[-1] == {"prompt": 5, "reply": "done", "fell": [[2, -1]]}
    assert fed.controls.calls[-1][1].startswith("console browser session 1")
