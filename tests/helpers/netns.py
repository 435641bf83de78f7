"""Network namespaces in tests: whether this machine lets a test make them (``unshare --net``, a veth pair)."""

from __future__ import annotations

import shutil
import subprocess

NO_NAMESPACES = "cannot create network namespaces and a veth pair here (needs unshare, ip, CAP_NET_ADMIN)"
"""The reason a test that needs them is skipped."""


def can_make_namespaces() -> bool:
    """Whether ``unshare --net`` works and a veth pair can be made in the namespace (root, or CAP_NET_ADMIN)."""
    if shutil.which("unshare") is None or shutil.which("ip") is None:
        return False
    probe = subprocess.run(["unshare", "--net", "sh", "-c", "ip link add va type veth peer name vb"],
                           capture_output=True, timeout=30)
    return probe.returncode == 0
