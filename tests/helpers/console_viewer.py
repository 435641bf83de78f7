"""A viewer on another machine (``python -m tests.helpers.console_viewer URL TOKEN CERT READY``, run in a network
namespace of its own by tests/rig/test_console_lab_network.py): headless Chromium driven by Playwright opens the
console at ``URL`` over HTTPS, trusting only the certificate ``CERT`` (its public key's SHA-256 pinned with
Chromium's ``--ignore-certificate-errors-spki-list``: any other certificate is refused as from an unknown CA), gives
the viewer's ``TOKEN``, watches live frames arrive and sends a pause anyway. ``READY`` is created once the browsers
run (the rig starts then). Prints one JSON object: what the browser saw."""

from __future__ import annotations

import base64
import hashlib
import json
import sys
import time
from pathlib import Path
from typing import Any

from cryptography import x509
from cryptography.hazmat.primitives.serialization import Encoding, PublicFormat

from tests.helpers.console import CHROMIUM, CHROMIUM_ARGS

PAGE_WAIT_S = 120.0
"""How long the viewer waits for the console to serve [s] (the rig starts its service, console and emulator)."""


def spki_pin(certificate: Path) -> str:
    """Base64 of the SHA-256 of the certificate's SubjectPublicKeyInfo: Chromium's pin of it."""
    cert = x509.load_pem_x509_certificate(certificate.read_bytes())
    spki = cert.public_key().public_bytes(Encoding.DER, PublicFormat.SubjectPublicKeyInfo)
    return base64.b64encode(hashlib.sha256(spki).digest()).decode()


def _goto_when_served(page: Any, url: str) -> None:
    from playwright.sync_api import Error

    deadline = time.monotonic() + PAGE_WAIT_S
    while True:
        try:
            page.goto(url)
            return
        except Error as exc:
            if "ERR_CONNECTION_REFUSED" not in str(exc) or time.monotonic() > deadline:
                raise
            time.sleep(0.2)


def watch(url: str, token: str, certificate: Path, ready: Path, profile: Path) -> dict[str, Any]:
    """What the viewer saw (module docstring)."""
    from playwright.sync_api import Error, sync_playwright

    seen: dict[str, Any] = {}
    with sync_playwright() as playwright:
        unpinned = playwright.chromium.launch(executable_path=str(CHROMIUM), headless=True, args=CHROMIUM_ARGS)
        pinned = playwright.chromium.launch_persistent_context(
            str(profile), executable_path=str(CHROMIUM), headless=True,
            args=[*CHROMIUM_ARGS, f"--ignore-certificate-errors-spki-list={spki_pin(certificate)}"])
        ready.touch()
        page = pinned.new_page()
        _goto_when_served(page, url)
        # a browser that does not know the certificate refuses the page
        try:
            unpinned.new_page().goto(url)
            seen["unpinned"] = "loaded"
        except Error as exc:
            seen["unpinned"] = str(exc).splitlines()[0]
        unpinned.close()
        page.fill("#token", token)
        page.click("#unlock")
        page.wait_for_function("() => document.getElementById('control-mode').textContent.includes('viewer')")
        seen["mode"] = page.inner_text("#control-mode")
        page.wait_for_function("() => window.consoleStats.draws >= 5 && "
                               "document.getElementById('state').dataset.state === 'running'", timeout=90_000)
        before = page.evaluate("window.consoleStats.frames")
        page.wait_for_function(f"() => window.consoleStats.frames > {before} + 5", timeout=30_000)
        seen["frames"] = [before, page.evaluate("window.consoleStats.frames")]
        seen["record"] = page.inner_text("#run-record")
        seen["pause_disabled"] = page.get_attribute("#pause", "disabled") is not None
        seen["pause"] = page.evaluate("""async () => {
            const session = await (await fetch('/api/session')).json();
            const r = await fetch('/api/control/pause', {method: 'POST', body: '{}', headers: {
                'Content-Type': 'application/json', 'X-Console-CSRF': session.csrf}});
            return [r.status, (await r.json()).message]; }""")
        seen["state_after"] = page.get_attribute("#state", "data-state")
        pinned.close()
    return seen


def main(argv: list[str]) -> None:
    url, token, certificate, ready = argv
    profile = Path(ready).with_name("viewer-profile")
    print(json.dumps(watch(url, token, Path(certificate), Path(ready), profile)), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
