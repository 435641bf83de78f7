"""Benchmark: the console under a Slowloris flood — one client opens N connections, each sending the start of a
request and then nothing, against the console's real server (uvicorn with ``rig.console.guard``'s defaults: 10 s
request timeout, 64 connections per client) in this process.

Reported: how long the flood took to open, how long the page's ``GET /api/state`` sent right after it took to be
answered and a second one after that, the guard's counters during the flood and 11 s later (every held connection
past the timeout), and the lines logged (one per reason, whatever N).

Usage: ``python benchmarks/console_slowloris.py [--connections 5000]``. Prints one JSON object.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import socket
import threading
import time

from rig.console import Console
from rig.console.guard import REQUEST_TIMEOUT, ConnectionGuard
from rig.console.server import console_server


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def get_state(port: int) -> tuple[float, dict]:
    """``GET /api/state``: seconds to the whole answer, and its JSON."""
    start = time.monotonic()
    with socket.create_connection(("127.0.0.1", port), timeout=60) as conn:
        conn.sendall(f"GET /api/state HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n".encode())
        data = b""
        while chunk := conn.recv(65536):
            data += chunk
    return time.monotonic() - start, json.loads(data.partition(b"\r\n\r\n")[2])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--connections", type=int, default=5000)
    args = parser.parse_args()
    logged: list[str] = []
    guard = ConnectionGuard(logged.append)
    port = free_port()
    server = console_server(Console(None, None), "127.0.0.1", port, guard=guard)
    threading.Thread(target=lambda: asyncio.run(server.serve()), daemon=True).start()
    while not server.started:
        time.sleep(0.02)
    held = []
    start = time.monotonic()
    for _ in range(args.connections):
        conn = socket.create_connection(("127.0.0.1", port), timeout=60)
        conn.sendall(b"GET / HTTP/1.1\r\nHost: x\r\nX-a: ")
        held.append(conn)
    opened_s = time.monotonic() - start
    first_s, state = get_state(port)
    second_s, _ = get_state(port)
    time.sleep(REQUEST_TIMEOUT + 1)
    print(json.dumps({"half_open_connections": args.connections, "flood_opened_s": round(opened_s, 2),
                      "state_after_flood_ms": round(first_s * 1000, 1), "state_again_ms": round(second_s * 1000, 1),
                      "during": state["connections"], "after_timeout": guard.stats(), "log_lines": logged}))
    for conn in held:
        conn.close()
    server.should_exit = True


if __name__ == "__main__":
    main()
