"""The console watched from another machine (issue 37, item 5; docs/lab-network.md): two network namespaces the test
creates (``unshare --net``, gone with their processes) joined by a veth pair — the operator's PC at 10.231.0.1
running ``rig run --console`` on its LAN address over HTTPS (a certificate made by ``rig certs make``, a tokens
file) with the emulated table on its loopback, and a viewer's machine at 10.231.0.9 where headless Chromium
(Playwright, tests/helpers/console_viewer.py) opens the page trusting only that certificate. The viewer sees the
run live, may not command: its pause is refused and is in the session's events with the viewer's name and address.
"""

from __future__ import annotations

import json
import os
import re
import secrets
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from protocols.signing_key import write_signing_key
from rig.certs import fingerprint, make_identity
from rig.session import read_session
from tests.helpers.console import CHROMIUM
from tests.helpers.netns import NO_NAMESPACES, can_make_namespaces
from tests.helpers.sequences import tiny

pytestmark = [pytest.mark.integration, pytest.mark.slow,  # processes, sockets, a browser; a whole session at 1x
              pytest.mark.skipif(not CHROMIUM.exists(),
                                 reason="Debian's chromium is not installed (apt-get install chromium)")]

ROOT = Path(__file__).parents[2]
RIG_ADDRESS, VIEWER_ADDRESS, PORT = "10.231.0.1", "10.231.0.9", 8443

@pytest.fixture(scope="module")
def namespaces() -> None:
    if not can_make_namespaces():
        pytest.skip(NO_NAMESPACES)


def _operator_pc_and_viewer(rig_command: list[str], rig_log: Path, viewer_command: list[str], viewer_out: Path,
                            ready: Path) -> subprocess.CompletedProcess[str]:
    """``viewer_command`` in a namespace at 10.231.0.9 (its stdout to ``viewer_out``) and, once it created
    ``ready``, ``rig_command`` in another at 10.231.0.1 (its output to ``rig_log``); prints ``rig=STATUS
    viewer=STATUS``."""
    viewer = (f"ip link set lo up && until ip link show vb >/dev/null 2>&1; do sleep 0.02; done && "
              f"ip addr add {VIEWER_ADDRESS}/24 dev vb && ip link set vb up && "
              f"exec {shlex.join(viewer_command)} > {shlex.quote(str(viewer_out))}")
    script = (f"ip link set lo up && {{ unshare --net sh -c {shlex.quote(viewer)} & }} && child=$! && "
              'while [ "$(readlink /proc/$child/ns/net)" = "$(readlink /proc/self/ns/net)" ]; do sleep 0.02; done && '
              f"ip link add va type veth peer name vb netns $child && ip addr add {RIG_ADDRESS}/24 dev va && "
              f"ip link set va up && "
              f"until [ -e {shlex.quote(str(ready))} ]; do kill -0 $child 2>/dev/null || break; sleep 0.05; done && "
              f"{shlex.join(rig_command)} > {shlex.quote(str(rig_log))} 2>&1; rig=$?; "
              "wait $child; echo rig=$rig viewer=$?")
    return subprocess.run(["unshare", "--net", "sh", "-c", script], capture_output=True, text=True, timeout=600,
                          cwd=ROOT, env={**os.environ, "COLUMNS": "200"})


def test_a_viewer_on_another_machine_watches_over_https_and_cannot_command(tmp_path: Path,
                                                                           namespaces: None) -> None:
    key = tmp_path / "rig.key"
    write_signing_key(key)
    web = make_identity(tmp_path / "web", "console", addresses=(RIG_ADDRESS,))
    certificate, private_key = web.certificate, web.key
    viewer_token = secrets.token_urlsafe(32)
    tokens = tmp_path / "tokens.toml"
    tokens.write_text(f'[[token]]\nname = "tablet"\nrole = "viewer"\ntoken = "{viewer_token}"\n\n'
                      f'[[token]]\nname = "control-room"\nrole = "operator"\ntoken = "{secrets.token_urlsafe(32)}"\n')
    tokens.chmod(0o600)
    sequence = tmp_path / "watched.toml"
    sequence.write_text(tiny(run_s=6.0))  # the session still runs when the viewer has looked on and sent its pause
    session, rig_log, viewer_out, ready = (tmp_path / "session.h5", tmp_path / "rig.log", tmp_path / "viewer.json",
                                          tmp_path / "viewer-ready")
    url = f"https://{RIG_ADDRESS}:{PORT}/"
    rig = [sys.executable, "-m", "rig.cli", "run", str(sequence), "--emulate", "--yes", "-o", str(session),
           "--key-file", str(key), "--console", f"{RIG_ADDRESS}:{PORT}", "--https-cert", str(certificate),
           "--https-key", str(private_key), "--tokens", str(tokens), "--console-linger", "0"]
    viewer = [sys.executable, "-m", "tests.helpers.console_viewer", url, viewer_token, str(certificate), str(ready)]
    done = _operator_pc_and_viewer(rig, rig_log, viewer, viewer_out, ready)
    said = rig_log.read_text() if rig_log.exists() else ""
    assert done.stdout.strip().endswith("rig=0 viewer=0"), done.stdout + done.stderr + said
    seen = json.loads(viewer_out.read_text())

    # the console printed its certificate's fingerprint, the one of the certificate the browser was given
    printed = re.search(r"SHA-256 fingerprint ([0-9A-F:]{95})", said.replace("\n", ""))
    assert printed is not None and printed.group(1) == fingerprint(certificate), said
    # a browser not given the certificate refuses the page; the one given it loaded it
    assert "ERR_CERT_AUTHORITY_INVALID" in seen["unpinned"], seen
    # the viewer watched the run live ...
    assert "viewer" in seen["mode"] and seen["pause_disabled"] is True, seen
    assert seen["frames"][1] > seen["frames"][0] + 5 and seen["record"].startswith("fema-"), seen
    # ... and its pause was refused; the session went on
    assert seen["pause"][0] == 403 and "'tablet' is a viewer" in seen["pause"][1], seen
    runs = read_session(session)["runs"]
    assert [run["status"] for run in runs] == ["completed", "completed"], [run["attrs"] for run in runs]
    controls = [event["text"] for run in runs for event in run["events"] if " control " in event["text"]]
    assert len(controls) == 1, controls
    assert " control pause from console browser session 1, unlocked " in controls[0]
    assert f" from {VIEWER_ADDRESS} (HeadlessChrome/" in controls[0]
    assert "with the viewer token of 'tablet'" in controls[0] and "(signed: rig key holder " in controls[0]
    assert controls[0].endswith("refused: refused by the console: a viewer may watch only"), controls[0]
