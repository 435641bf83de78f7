"""Bidirectional records from one file per component: the spec ``H1+H2`` or ``H1+H2+UP``.

Example (PEER NGA-West2 names)::

    RSN6_IMPVALL.I_I-ELC180.AT2+RSN6_IMPVALL.I_I-ELC270.AT2+RSN6_IMPVALL.I_I-ELC-UP.AT2

The files, in this order, are the first horizontal (``acc_h``, drives surge), the second horizontal
(``acc_h2``, drives sway) and, optionally, the vertical component (``acc_v``, positive up as in PEER's
``-UP`` files). Each is read by its format's reader (`files`) and must hold one component, in its place
(`component.check_place`): a file that says it holds a vertical component (COSMOS orientation code, PEER line
2, a name ending in ``-UP``, ``UP``, ``-V``, ``DWN``, ``-DN``, or a SEED channel such as ``.HNZ``, ``.BHZ.00``,
``.00.HNZ``: see `component`) is refused in a horizontal place, one that says it holds a horizontal
component is refused in the vertical place. All components must have the same dt (relative tolerance 1e-6)
and the same number of samples: otherwise the error names both files and both values.
The record's name joins the file stems with ``+``.

A spec is a component set when it contains ``+`` and is not itself the path of an existing file.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from .component import VERTICAL, check_place, name_component
from .files import read_record_file
from .motion import GroundMotion, RecordError, array_sha256
from .source import DT_RTOL

SEPARATOR = "+"
_ROLES = ("h", "h2", "v")


def split_components(spec: str) -> list[str] | None:
    """The component files of an ``H1+H2[+UP]`` spec, or None if ``spec`` is not one."""
    if SEPARATOR not in spec or Path(spec).expanduser().exists():
        return None
    parts = [part.strip() for part in spec.split(SEPARATOR)]
    if len(parts) not in (2, 3) or not all(parts):
        raise RecordError(f"{spec!r}: expected H1+H2 or H1+H2+UP, two or three record files joined by '+'")
    return parts


def read_components(
    paths: Sequence[str | Path], *, dt: float | None = None, units: str | None = None
) -> GroundMotion:
    """One bidirectional `GroundMotion` from two (h, h2) or three (h, h2, v) single-component files."""
    if len(paths) not in (2, 3):
        raise RecordError(f"expected 2 or 3 component files (H1+H2[+UP]), got {len(paths)}")
    for place, path in enumerate(paths[:2], start=1):
        named = name_component(path)
        if named is not None and named[0] == VERTICAL:
            raise RecordError(
                f"{path}: horizontal component {place} is named like a vertical one ({named[1]}); "
                "expected H1+H2+UP with the vertical component last"
            )
    motions = [read_record_file(path, dt=dt, units=units) for path in paths]
    for path, motion in zip(paths, motions, strict=True):
        if motion.acc_h2 is not None or motion.acc_v is not None:
            raise RecordError(f"{path}: holds several components; expected one component per file in H1+H2[+UP]")
    for path, motion, role in zip(paths, motions, _ROLES, strict=False):
        check_place(path, motion, role)
    first, path1 = motions[0], paths[0]
    for path, motion in zip(paths[1:], motions[1:], strict=True):
        if not math.isclose(motion.dt, first.dt, rel_tol=DT_RTOL):
            raise RecordError(
                f"{path1} has dt = {first.dt:g} s but {path} has dt = {motion.dt:g} s; "
                "expected the components of one record to share dt"
            )
        if motion.npts != first.npts:
            raise RecordError(
                f"{path1} has {first.npts} samples but {path} has {motion.npts}; "
                "expected the same number of samples in every component"
            )
    components = dict(zip(_ROLES, motions, strict=False))
    provenance = {
        "source": "files",
        "format": "component set H1+H2" + ("+UP" if "v" in components else ""),
        "files": [str(Path(p).expanduser().resolve()) for p in paths],
        "npts": first.npts,
        "dt": first.dt,
        "sha256": array_sha256(first.acc_h),
        "components": {role: motion.provenance for role, motion in components.items()},
    }
    return GroundMotion(
        name=SEPARATOR.join(m.name for m in motions),
        dt=first.dt,
        acc_h=components["h"].acc_h,
        acc_h2=components["h2"].acc_h,
        acc_v=components["v"].acc_h if "v" in components else None,
        provenance=provenance,
    )


def read_file_spec(
    spec: str, *, dt: float | None = None, units: str | None = None, accept_vertical: bool = False
) -> GroundMotion:
    """A record file, or the component set of an ``H1+H2[+UP]`` spec.

    A file that holds only a vertical component is refused unless ``accept_vertical`` (the user's explicit
    wish to drive surge with it, ``--accept-vertical``); see `component.check_place`.
    """
    parts = split_components(spec)
    if parts is not None:
        return read_components(parts, dt=dt, units=units)
    motion = read_record_file(spec, dt=dt, units=units)
    if motion.acc_h2 is None and motion.acc_v is None:
        check_place(spec, motion, "alone", accept_vertical=accept_vertical)
    return motion
