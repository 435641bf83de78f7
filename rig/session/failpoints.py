"""Test hooks, inert unless their environment variables are set (never outside tests).

* ``RIG_SESSION_FAILPOINT=name[:n]``: the n-th (default first) pass of `hit` with that name ``SIGKILL``s the
  process at that exact step.
* ``RIG_SESSION_FORCE_SHADOW=1``: every commit takes the copy-and-rename path (`rig.session.atomic`), which
  normal sessions almost never need, so that the kill tests can crash it too.
"""

from __future__ import annotations

import os
import signal

_SPEC = os.environ.get("RIG_SESSION_FAILPOINT", "")
_NAME, _, _COUNT = _SPEC.rpartition(":")
if not _COUNT.isdigit():  # no pass number given
    _NAME, _COUNT = _SPEC, "1"
_TARGET = int(_COUNT)
_seen: dict[str, int] = {}
FORCE_SHADOW = os.environ.get("RIG_SESSION_FORCE_SHADOW", "") == "1"


def hit(name: str) -> None:
    """Kill this process with SIGKILL if ``name`` is the configured crash point and its pass has come."""
    if not _NAME or name != _NAME:
        return
    _seen[name] = _seen.get(name, 0) + 1
    if _seen[name] == _TARGET:
        os.kill(os.getpid(), signal.SIGKILL)
