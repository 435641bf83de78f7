"""The lab network across two hosts, as a lab sets it up (docs/lab-network.md): two network namespaces the test
creates (``unshare --net``, gone with their processes) joined by a veth pair, the rig at 10.231.0.1 and the table
controller (``python -m sim_table``) at 10.231.0.2. Nothing leaves the namespaces: no traffic goes to an address
the test did not make.

``rig run`` plays a one-run sequence on the table over MAVLink and over zenoh with mutual TLS; a client with a
certificate of another CA, one that trusts another CA, and a plain ``tcp/`` table URL off loopback are each refused
with one line that says which; the link taken down mid-stream (``ip link set va down`` in the rig's namespace) ends
the run ``interrupted: table link lost`` within the link timeout, the feedback up to the cut kept in the session
file, and the controller stops the table by itself.
"""

from __future__ import annotations

import errno
import json
import os
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from analysis.table.link import LinkSettings
from drivers.controller import LINK_GRACE, WAIT_SLICE
from protocols.signing_key import write_signing_key
from rig.certs import make_identity
from rig.emulator import specimen_flags
from rig.sequence import load_sequence
from rig.session import read_session
from tests.helpers.netns import NO_NAMESPACES, can_make_namespaces

pytestmark = pytest.mark.integration  # starts processes and opens sockets (tests/conftest.py)

ROOT = Path(__file__).parents[2]
RIG_ADDRESS, TABLE_ADDRESS = "10.231.0.1", "10.231.0.2"

_SEQUENCE = """
name = "labnet"
angles_deg = [0]
records = [{{ record = "fema-nearfield:NORTHR/RRS_032", window_s = [0.5, 2.0] }}]
[rig]
config = {rig_config!r}
[drive]
corner_hz = 1.0
settle_s = 0.2
[operator]
confirm_before_run = false
ask_detections = false
[[bodies]]
table5 = 4
x = 0.0
y = -0.15
"""


@pytest.fixture(scope="module")
def namespaces() -> None:
    if not can_make_namespaces():
        pytest.skip(NO_NAMESPACES)


def _two_hosts(table_command: list[str], table_log: Path, rig_command: list[str], timeout: float = 240.0,
               ) -> subprocess.CompletedProcess[str]:
    """Run ``table_command`` (the controller, until SIGINT) in a namespace at 10.231.0.2 and, once it logged
    ``listening``, ``rig_command`` in another at 10.231.0.1; the rig command's result (its exit status, stdout,
    stderr)."""
    log = shlex.quote(str(table_log))
    table = (f"ip link set lo up && until ip link show vb >/dev/null 2>&1; do sleep 0.02; done && "
             f"ip addr add {TABLE_ADDRESS}/24 dev vb && ip link set vb up && exec {shlex.join(table_command)} 2> {log}")
    script = (f"ip link set lo up && {{ unshare --net sh -c {shlex.quote(table)} & }} && child=$! && "
              'while [ "$(readlink /proc/$child/ns/net)" = "$(readlink /proc/self/ns/net)" ]; do sleep 0.02; done && '
              f"ip link add va type veth peer name vb netns $child && ip addr add {RIG_ADDRESS}/24 dev va && "
              f"ip link set va up && "
              f"until grep -qs listening {log}; do kill -0 $child 2>/dev/null || exit 97; sleep 0.05; done && "
              f"{shlex.join(rig_command)}; status=$?; kill -INT $child; wait $child; exit $status")
    return subprocess.run(["unshare", "--net", "sh", "-c", script], capture_output=True, text=True, timeout=timeout,
                          cwd=ROOT)


def _sequence(tmp_path: Path, window: str = "[0.5, 2.0]") -> tuple[Path, list[str]]:
    path = tmp_path / "labnet.toml"
    text = _SEQUENCE.format(rig_config=str(ROOT / "examples" / "rig-table4.toml"))
    path.write_text(text.replace("window_s = [0.5, 2.0]", f"window_s = {window}"))
    return path, specimen_flags(load_sequence(path).bodies)


def _identities(tmp_path: Path) -> Path:
    certs = tmp_path / "certs"
    make_identity(certs, "table", addresses=(TABLE_ADDRESS,))
    make_identity(certs, "rig")
    return certs


def _tls(certs: Path, name: str, ca: Path | None = None) -> list[str]:
    return ["--tls-ca", str(ca or certs / "ca.pem"), "--tls-cert", str(certs / f"{name}.pem"),
            "--tls-key", str(certs / f"{name}.key")]


@pytest.mark.slow
@pytest.mark.parametrize("transport", ["mavlink", "zenoh-tls"])
def test_rig_run_across_two_hosts(transport: str, tmp_path: Path, namespaces: None) -> None:
    sequence, bodies = _sequence(tmp_path)
    key = tmp_path / "rig.key"
    write_signing_key(key)
    certs = _identities(tmp_path)
    if transport == "mavlink":
        listen = url = f"mavlink://{TABLE_ADDRESS}:14600"
        table_tls: list[str] = []
        rig_tls: list[str] = []
    else:
        listen = url = f"zenoh://{TABLE_ADDRESS}:7447/lab"
        table_tls, rig_tls = _tls(certs, "table"), _tls(certs, "rig")
    table = [sys.executable, "-m", "sim_table", "--listen", listen, "--key-file", str(key), *bodies, *table_tls,
             "--counters", str(tmp_path / "counters.json")]
    output = tmp_path / "session.h5"
    rig = [sys.executable, "-m", "rig.cli", "run", str(sequence), "--table", url, "--key-file", str(key), "--yes",
           "--json", "-o", str(output), *rig_tls]
    done = _two_hosts(table, tmp_path / "table.log", rig)
    assert done.returncode == 0, done.stderr + (tmp_path / "table.log").read_text()
    outcome = json.loads(done.stdout)
    assert outcome["complete"] is True and outcome["runs_done"] == outcome["runs_total"] == 1, outcome
    counters = json.loads((tmp_path / "counters.json").read_text())
    assert counters["underruns"] == 0 and counters["state"] == "idle", counters


def test_certificates_the_other_side_does_not_trust_are_refused_clearly(tmp_path: Path, namespaces: None) -> None:
    """The table listens with the lab's certificate. A rig given a certificate of another lab (another CA signed it)
    is refused before it sends anything; a rig whose whole identity is another lab's refuses the table's certificate
    (an unknown CA): each says so in one line, naming the file."""
    sequence, bodies = _sequence(tmp_path)
    key = tmp_path / "rig.key"
    write_signing_key(key)
    certs = _identities(tmp_path)
    other = tmp_path / "other"
    make_identity(other, "rig")
    table = [sys.executable, "-m", "sim_table", "--listen", f"zenoh://{TABLE_ADDRESS}:7447/lab", "--key-file",
             str(key), *bodies, *_tls(certs, "table")]
    run = [sys.executable, "-m", "rig.cli", "run", str(sequence), "--table", f"zenoh://{TABLE_ADDRESS}:7447/lab",
           "--key-file", str(key), "--yes", "-o", str(tmp_path / "s.h5")]
    attempts = [  # (our CA, our certificate's directory): a wrong certificate, then an unknown CA
        (certs / "ca.pem", other), (other / "ca.pem", other)]
    script = " ; ".join(f"{shlex.join([*run, *_tls(directory, 'rig', ca)])} ; echo exit=$?"
                        for ca, directory in attempts)
    done = _two_hosts(table, tmp_path / "table.log", ["sh", "-c", script])
    errors = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    assert [line for line in done.stdout.splitlines() if line.startswith("exit=")] == ["exit=2", "exit=2"], done
    assert len(errors) == 2, done.stderr
    assert errors[0] == (f"error: --tls-cert {other / 'rig.pem'}: not signed by the CA {certs / 'ca.pem'} "
                         "(CN=shaketable-rig lab CA (certs))")
    assert (f"the certificate of the listener at {TABLE_ADDRESS}:7447 is not trusted by the CA "
            f"{other / 'ca.pem'}") in errors[1]
    assert not (tmp_path / "s.h5").exists()  # nothing was written


def test_a_plain_table_url_off_loopback_is_refused_before_any_link(tmp_path: Path) -> None:
    """No namespace needed: the refusal comes before a socket is opened."""
    sequence, _ = _sequence(tmp_path)
    key = tmp_path / "rig.key"
    write_signing_key(key)
    done = subprocess.run([sys.executable, "-m", "rig.cli", "run", str(sequence), "--table",
                           f"zenoh://{TABLE_ADDRESS}:7447/lab", "--key-file", str(key), "--yes"],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1].startswith(
        f"error: the table at zenoh://{TABLE_ADDRESS}:7447/lab cannot be used: table URL "
        f"'zenoh://{TABLE_ADDRESS}:7447/lab': endpoint 'tcp/{TABLE_ADDRESS}:7447' is off loopback and not encrypted")
    assert "Traceback" not in done.stderr


def test_rig_table_list_finds_the_table_across_hosts_over_tls(tmp_path: Path, namespaces: None) -> None:
    """The controller declares a liveliness token: ``rig table list`` on the other host finds it, with its transport
    and its state verified with the rig's key."""
    key = tmp_path / "rig.key"
    write_signing_key(key)
    certs = _identities(tmp_path)
    table = [sys.executable, "-m", "sim_table", "--listen", f"zenoh://{TABLE_ADDRESS}:7447/lab", "--key-file",
             str(key), *_tls(certs, "table"), "--counters", str(tmp_path / "counters.json")]
    listing = [sys.executable, "-m", "rig.cli", "table", "list", "--connect", f"tls/{TABLE_ADDRESS}:7447",
               "--key-file", str(key), "--json", *_tls(certs, "rig")]
    done = _two_hosts(table, tmp_path / "table.log", listing, timeout=120)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout) == {"found": [{
        "name": "lab", "role": "table", "transport": f"zenoh mutual TLS via tls/{TABLE_ADDRESS}:7447",
        "state": "idle"}]}


@pytest.mark.slow
@pytest.mark.parametrize("transport", ["mavlink", "zenoh-tls"])
def test_the_link_lost_between_hosts_ends_the_run_interrupted_with_its_samples(transport: str, tmp_path: Path,
                                                                             namespaces: None) -> None:
    """A 7.5 s record at real time; 1.5 s into it the rig's end of the veth goes down (tests/helpers/link_cut.py):
    the run ends ``interrupted: table link lost`` within the link timeout (with the grace, one wait slice and the
    lead of chunks already due — the bound of tests/rig/test_real_time.py), the poses measured up to the cut are in
    the session file, and the table, hearing no host, stops itself (its watchdog, or its buffer run dry)."""
    sequence, bodies = _sequence(tmp_path, "[0.5, 8.0]")
    key = tmp_path / "rig.key"
    write_signing_key(key)
    certs = _identities(tmp_path)
    if transport == "mavlink":
        listen = url = f"mavlink://{TABLE_ADDRESS}:14600"
        table_tls: list[str] = []
    else:
        listen, url = f"zenoh://{TABLE_ADDRESS}:7447/lab", f"zenoh://{TABLE_ADDRESS}:7447/lab"
        table_tls = _tls(certs, "table")
    table = [sys.executable, "-m", "sim_table", "--listen", listen, "--key-file", str(key), *bodies, *table_tls,
             "--counters", str(tmp_path / "counters.json")]
    session = tmp_path / "session.h5"
    rig = [sys.executable, "-m", "tests.helpers.link_cut", str(sequence), url, str(key), str(session), "va", "1.5"]
    if transport != "mavlink":
        rig += [str(certs / "ca.pem"), str(certs / "rig.pem"), str(certs / "rig.key")]
    done = _two_hosts(table, tmp_path / "table.log", rig)
    assert done.returncode == 0, done.stderr + (tmp_path / "table.log").read_text()
    outcome = json.loads(done.stdout.strip().splitlines()[-1])
    assert outcome["state"] == "faulted", outcome
    assert "table link lost" in outcome["message"], outcome
    link = LinkSettings()
    assert outcome["ended_after_s"] < link.link_timeout_s + LINK_GRACE + WAIT_SLICE + link.lead_s + 2.0, outcome
    (run,) = read_session(session)["runs"]
    assert run["status"] == "interrupted" and run["attrs"]["reason"].startswith("table link lost"), run["attrs"]
    assert any(event["text"].startswith("interrupted: table link lost") for event in run["events"]), run["events"]
    if transport == "mavlink":  # the sends the network refused are named
        assert f"sends failed: {os.strerror(errno.ENETUNREACH)}" in run["attrs"]["reason"], run["attrs"]
    poses = run["pose"]
    assert len(poses) > 0
    # nothing lost: the feedback is there up to the cut (less the status period and a busy machine's slack), in order
    t = poses[:, 0]
    assert (t[1:] >= t[:-1]).all()
    assert t[-1] >= outcome["played_at_cut_s"] - 0.5, (t[-1], outcome)
    counters = json.loads((tmp_path / "counters.json").read_text())
    # the table, hearing no host, stopped itself: stopping (decelerating, homing) or already faulted, by its
    # heartbeat or stream watchdog or by its buffer running dry (the lead buffered and the watchdog are both ~1 s:
    # which trips first is a race, and each is a stopping fault)
    assert counters["state"] in ("stopping", "faulted"), counters
    assert {"HEARTBEAT_LOST", "STREAM_SILENT", "UNDERRUN"} & set(counters["faults"]), counters
