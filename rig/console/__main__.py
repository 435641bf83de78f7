"""``python -m rig.console --connect ENDPOINT --http HOST:PORT [--key-file FILE] [--rig NAME]``: the console as its
own process (what ``rig console``, ``rig serve --http`` and ``rig run --console`` run)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from rig.console.server import ConsoleError, serve_console


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rig.console", description=__doc__)
    parser.add_argument("--connect", required=True, help="the rig service's zenoh endpoint")
    parser.add_argument("--http", required=True, help="HOST:PORT to serve the page on (loopback)")
    parser.add_argument("--key-file", type=Path, default=None, help="the rig's key (default $SHAKETABLE_MAVLINK_KEY)")
    parser.add_argument("--rig", default="rig", help="the rig's name in the key space")
    args = parser.parse_args(argv)

    def say(message: str) -> None:
        print(f"rig console: {message}", file=sys.stderr, flush=True)

    try:
        serve_console(args.connect, args.http, key_file=args.key_file, rig=args.rig, say=say)
    except ConsoleError as exc:
        say(f"error: {exc}")
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
