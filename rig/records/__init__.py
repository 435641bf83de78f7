"""Earthquake records: readers and the built-in suites.

A record spec is one of:

* ``SUITE:NAME`` — a component of a built-in suite, e.g. ``fema-farfield:NORTHR/MUL009``
  (``fema:NAME`` looks in both FEMA P695 suites);
* a path to a PEER ``.AT2`` file;
* for `load_records` only, a bare suite name: ``fema-farfield`` (44), ``fema-nearfield`` (56) or
  ``fema`` (both, 100 horizontal components).

Every record comes back as a `GroundMotion` (dt in s, acceleration in g).
"""

from __future__ import annotations

import difflib
from pathlib import Path

from .fema import SUITES, load_suite, load_suite_record, suite_names
from .motion import G, GroundMotion, RecordError
from .peer import read_at2

#: Names that stand for several suites at once.
SUITE_ALIASES: dict[str, tuple[str, ...]] = {"fema": SUITES}

#: File suffixes (lower case) with a reader.
FILE_SUFFIXES: tuple[str, ...] = (".at2",)

__all__ = [
    "FILE_SUFFIXES",
    "SUITES",
    "SUITE_ALIASES",
    "G",
    "GroundMotion",
    "RecordError",
    "expand_suite",
    "load_record",
    "load_records",
    "load_suite",
    "load_suite_record",
    "read_at2",
    "suite_names",
]


def expand_suite(name: str) -> tuple[str, ...] | None:
    """The suites a name stands for (a suite or an alias such as ``fema``), or None if it is neither."""
    if name in SUITES:
        return (name,)
    return SUITE_ALIASES.get(name)


def _spec_help() -> str:
    suites = ", ".join((*SUITES, *SUITE_ALIASES))
    return f"expected SUITE:NAME (suites: {suites}; names: `rig records list SUITE`) or a path to a .AT2 file"


def _load_from_suites(suites: tuple[str, ...], name: str, spec: str) -> GroundMotion:
    """A named component from the first of ``suites`` that has it."""
    if len(suites) == 1:
        return load_suite_record(suites[0], name)
    names = [n for suite in suites for n in suite_names(suite)]
    for suite in suites:
        if name in suite_names(suite):
            return load_suite_record(suite, name)
    close = difflib.get_close_matches(name, names, n=3)
    hint = f" Did you mean: {', '.join(close)}?" if close else ""
    raise RecordError(
        f"no record {name!r} in suites {', '.join(suites)}.{hint} "
        f"List the names with `rig records list {spec.partition(':')[0]}`."
    )


def _looks_like_suite(prefix: str) -> bool:
    """True for a ``SUITE`` part of ``SUITE:NAME`` (not a path, not a Windows drive letter)."""
    return len(prefix) > 1 and not any(c in prefix for c in "/\\.")


def _load_file(spec: str) -> GroundMotion:
    """A record file by path, dispatched on its suffix."""
    path = Path(spec).expanduser()
    if path.suffix.lower() not in FILE_SUFFIXES:
        if not path.exists():
            raise RecordError(f"{spec!r} is neither a record nor an existing file; {_spec_help()}")
        raise RecordError(f"{spec}: unsupported record file type {path.suffix!r}; readable: .AT2")
    return read_at2(path)


def load_record(spec: str) -> GroundMotion:
    """One record from ``SUITE:NAME`` or a file path (see the module docstring)."""
    spec = spec.strip()
    if not spec:
        raise RecordError(f"empty record spec; {_spec_help()}")
    if expand_suite(spec) is not None:
        count = sum(len(suite_names(s)) for s in expand_suite(spec) or ())
        raise RecordError(
            f"{spec!r} is a suite of {count} records, not one record; use {spec}:NAME "
            f"(names: `rig records list {spec}`)"
        )
    prefix, sep, name = spec.partition(":")
    suites = expand_suite(prefix) if sep else None
    if suites is not None:
        if not name:
            raise RecordError(f"{spec!r}: missing record name after ':'; {_spec_help()}")
        return _load_from_suites(suites, name, spec)
    if sep and _looks_like_suite(prefix) and not Path(spec).exists():
        valid = ", ".join((*SUITES, *SUITE_ALIASES))
        raise RecordError(f"unknown record suite {prefix!r} in {spec!r}; valid suites: {valid}")
    return _load_file(spec)


def load_records(spec: str) -> list[GroundMotion]:
    """All records a spec names: a whole suite (``fema-farfield``, ``fema-nearfield``, ``fema``) or one."""
    suites = expand_suite(spec.strip())
    if suites is not None:
        return [motion for suite in suites for motion in load_suite(suite)]
    return [load_record(spec)]
