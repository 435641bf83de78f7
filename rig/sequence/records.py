"""The records of a sequence: file paths read from the sequence's folder, ``records_from``, time windows.

``records_from = { suite = "fema", strongest = 25 }`` takes the 25 components of the suite with the
largest **PGA** (peak |acceleration| of the horizontal component as recorded, `GroundMotion.pga`), strongest
first; ties keep the suite's order. Without ``strongest`` it takes the whole suite in its own order.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rig.records import LIBRARY, SUITES, GroundMotion, RecordError, expand_suite, load_record, load_records
from rig.records.motion import array_sha256
from rig.records.pairs import SEPARATOR

from .model import NEGATED_LABEL, RecordEntry


def is_named(spec: str) -> bool:
    """True for ``SUITE:NAME`` and ``library:NAME`` (not a file)."""
    prefix, sep, _ = spec.strip().partition(":")
    return bool(sep) and (prefix == LIBRARY or expand_suite(prefix) is not None)


def resolve_spec(spec: str, base_dir: Path) -> str:
    """``spec`` with relative file paths (also inside ``H1+H2[+UP]``) made absolute from ``base_dir``."""
    spec = spec.strip()
    if is_named(spec):
        return spec

    def absolute(part: str) -> str:
        path = Path(part.strip()).expanduser()
        return str(path if path.is_absolute() else base_dir / path)

    whole = absolute(spec)
    if SEPARATOR not in spec or Path(whole).exists():
        return whole
    return SEPARATOR.join(absolute(part) for part in spec.split(SEPARATOR))


def expand_records_from(suite: str, strongest: int | None) -> list[str]:
    """``SUITE:NAME`` specs of a suite's strongest components by PGA (module docstring).

    Raises ValueError (`RecordError`) for an unknown suite or more components than the suite has.
    """
    if suite != LIBRARY and expand_suite(suite) is None:
        raise RecordError(f"unknown suite {suite!r}; expected one of {', '.join((*SUITES, 'fema', LIBRARY))}")
    motions = load_records(suite)
    if strongest is not None:
        if strongest > len(motions):
            raise RecordError(f"strongest = {strongest} but suite {suite!r} has {len(motions)} components")
        order = sorted(range(len(motions)), key=lambda i: (-motions[i].pga, i))
        motions = [motions[i] for i in order[:strongest]]
    out = []
    for motion in motions:
        source = motion.provenance.get("suite") if suite != LIBRARY else LIBRARY
        out.append(f"{source or suite}:{motion.name}")
    return out


def load_entry(entry: RecordEntry) -> GroundMotion:
    """The entry's record, cut to its window (``window`` [s] from the record's first sample), in its polarity
    (`negated`).

    Raises `RecordError` when the record does not resolve or the window is not inside the record.
    """
    motion = _window(entry, load_record(entry.resolved, dt=entry.dt, units=entry.units))
    return negated(motion) if entry.polarity < 0 else motion


def negated(motion: GroundMotion) -> GroundMotion:
    """The record with its fall-line component (``acc_h``) negated, the second horizontal and the vertical as
    recorded (`RecordEntry.polarity`); named ``NAME (negated)``, ``polarity`` −1 in its provenance."""
    acc_h = -motion.acc_h
    provenance = {**motion.provenance, "polarity": -1, "sha256": array_sha256(acc_h)}
    return GroundMotion(name=f"{motion.name}{NEGATED_LABEL}", dt=motion.dt, acc_h=acc_h, acc_v=motion.acc_v,
                        acc_h2=motion.acc_h2, provenance=provenance)


def _window(entry: RecordEntry, motion: GroundMotion) -> GroundMotion:
    """The part of ``motion`` inside the entry's window (all of it without one)."""
    if entry.window is None:
        return motion
    t0, t1 = entry.window
    if t1 > motion.duration + 0.5 * motion.dt:
        raise RecordError(f"window_s = [{t0:g}, {t1:g}] s ends after the record ({motion.name!r} lasts "
                          f"{motion.duration:g} s); expected t1 ≤ {motion.duration:g} s")
    first, last = round(t0 / motion.dt), round(t1 / motion.dt)
    if last - first < 4:
        raise RecordError(f"window_s = [{t0:g}, {t1:g}] s holds fewer than 5 samples at dt = {motion.dt:g} s")

    def cut(values: np.ndarray | None) -> np.ndarray | None:
        return None if values is None else values[first:last + 1]

    acc_h = motion.acc_h[first:last + 1]
    provenance = {**motion.provenance, "window_s": [t0, t1], "window_samples": [first, last + 1],
                  "record_sha256": motion.provenance.get("sha256"), "npts": int(acc_h.size),
                  "sha256": array_sha256(acc_h)}
    return GroundMotion(name=f"{motion.name} [{t0:g}-{t1:g} s]", dt=motion.dt, acc_h=acc_h,
                        acc_v=cut(motion.acc_v), acc_h2=cut(motion.acc_h2), provenance=provenance)
