"""The rig's side of the link-loss test (tests/transports/test_lab_network_netns.py), run inside the rig's network
namespace as ``python -m tests.helpers.link_cut SEQUENCE URL KEY_FILE SESSION LINK CUT_S [CA CERT KEY]``: plays
SEQUENCE on the table at URL (a zenoh one with the TLS identity CA, CERT, KEY) into the new session file SESSION
and, once CUT_S seconds of the drive have been played (the samples sent, less the lead the chunks go ahead by),
takes the network interface LINK down (``ip link set LINK down``), as a cable pulled out. Prints one JSON object:
the orchestrator's final ``state`` and ``message``, ``played_at_cut_s`` (the drive time played when the link went
down) and ``ended_after_s`` (host seconds from the cut to the session's end)."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from protocols.zenoh.tls import load_tls
from rig.orchestrator import Orchestrator, OrchestratorState
from rig.sequence import load_sequence
from tests.helpers.sequences import new_log, wait_for


def main(argv: list[str]) -> int:
    sequence_file, url, key_file, session, link, cut_s = argv[:6]
    options: dict[str, Any] = {"key_file": key_file}
    if argv[6:]:
        options["tls"] = load_tls(*argv[6:9])
    sequence = load_sequence(Path(sequence_file))
    rate, lead = sequence.table.controller_rate, sequence.table.link.lead_s
    log = new_log(sequence, Path(session))
    orchestrator = Orchestrator(sequence, url, log, table_options=options)
    result: list[OrchestratorState | BaseException] = []

    def work() -> None:
        try:
            result.append(orchestrator.run())
        except BaseException as exc:  # said in the JSON, not lost in a thread
            result.append(exc)

    worker = threading.Thread(target=work, daemon=True)
    worker.start()
    wait_for(lambda: orchestrator.progress.samples_sent >= (float(cut_s) + lead) * rate or not worker.is_alive(),
             timeout=180.0)
    sent = orchestrator.progress.samples_sent
    subprocess.run(["ip", "link", "set", link, "down"], check=True)
    cut = time.monotonic()
    worker.join(180)
    ended = time.monotonic() - cut
    log.close()
    outcome = result[0] if result else None
    print(json.dumps({"state": outcome.value if isinstance(outcome, OrchestratorState) else repr(outcome),
                      "message": orchestrator.progress.message, "played_at_cut_s": sent / rate - lead,
                      "ended_after_s": ended}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
