"""The bodies on the table checked against the sequence's, at connect and before any motion (issue 22).

The table reports the bodies on its plate (`drivers.bodies`, ``docs/table-controller.md``: the emulator its
specimens, a real controller a body per overturn-detector channel). Body k of the report is the sequence's k-th
body (the emulator numbers them in the order they were placed, as ``specimen_flags`` passes them). Compared:

- the **number** of bodies, always (a real table whose detectors know no sizes: that is all it can tell);
- each body's breadth b, height h, depth and place (x, y) on the plate, within :data:`TOLERANCE`, when the table
  reports sizes (not all zero).

A table that does not report bodies (`TableController.bodies` None: a CANopen detector without the body objects)
is not checked.
"""

from __future__ import annotations

from collections.abc import Sequence

from drivers.bodies import TableBody
from rig.sequence import PlacedBody

TOLERANCE = 1e-3
"""Largest difference in a size or place that still matches [m] (the wire carries float32: ~1e-7 relative)."""


class BodiesMismatchError(ValueError):
    """The table's bodies are not the sequence's; the message lists both."""


def _placed(body: PlacedBody) -> str:
    return (f"{body.name} {body.body.b:.3f}x{body.body.h:.3f} m (depth {body.depth:.3f} m) at ({body.x:.3f}, "
            f"{body.y:.3f}) m")


def _reported(body: TableBody) -> str:
    if not (body.b or body.h or body.depth):
        return f"channel {body.body_id} (size and place not reported)"
    return (f"body {body.body_id} {body.b:.3f}x{body.h:.3f} m (depth {body.depth:.3f} m) at ({body.x:.3f}, "
            f"{body.y:.3f}) m")


def mismatch(wanted: Sequence[PlacedBody], reported: Sequence[TableBody]) -> str | None:
    """What differs between the sequence's bodies and the table's (module docstring), or None when they match."""
    if len(wanted) != len(reported):
        return f"the sequence has {len(wanted)} bodies, the table {len(reported)}"
    for k, (body, seen) in enumerate(zip(wanted, reported, strict=True)):
        if not (seen.b or seen.h or seen.depth):
            continue  # a detector channel without a size: only the count is compared
        pairs = (("b", body.body.b, seen.b), ("h", body.body.h, seen.h), ("depth", body.depth, seen.depth),
                 ("x", body.x, seen.x), ("y", body.y, seen.y))
        differ = [f"{name} {mine:.3f} m against {theirs:.3f} m" for name, mine, theirs in pairs
                  if abs(mine - theirs) > TOLERANCE]
        if differ:
            return f"body {k + 1} ({body.name}): " + ", ".join(differ)
    return None


def check_bodies(wanted: Sequence[PlacedBody], reported: Sequence[TableBody] | None, table: str) -> None:
    """BodiesMismatchError naming both lists unless the table at ``table`` reports the sequence's bodies (or
    reports none: ``reported`` None)."""
    if reported is None:
        return
    problem = mismatch(wanted, reported)
    if problem is None:
        return
    ours = "; ".join(_placed(b) for b in wanted) or "none"
    theirs = "; ".join(_reported(b) for b in reported) or "none"
    raise BodiesMismatchError(f"the bodies on the table at {table} are not the sequence's ({problem}): the sequence "
                              f"places {ours} — the table reports {theirs}. Nothing moved: place the sequence's "
                              "bodies (or run the sequence written for these) and start again")
