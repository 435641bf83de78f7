"""Earthquake records: readers, the built-in suites and the user's record library.

A record spec is one of:

* ``SUITE:NAME`` — a component of a built-in suite, e.g. ``fema-farfield:NORTHR/MUL009``
  (``fema:NAME`` looks in both FEMA P695 suites: ``fema-farfield``, ``fema-nearfield``);
* ``library:NAME`` — a record imported into the user's record library (`library`);
* a path to a record file, read by its suffix (`files`): ``.AT2`` (PEER), ``.txt``/``.dat``/``.acc``
  (plain text), ``.csv``, ``.h5``/``.hdf5`` (the project's own record file), ``.V1``/``.V2``/``.V1C``/``.V2C``
  (COSMOS strong-motion files from CESMD or the USGS: one acceleration channel, or two horizontal
  and an optional vertical one as one bidirectional record);
* ``H1+H2`` or ``H1+H2+UP`` — one bidirectional record from two horizontal files and, optionally, a
  vertical one (`pairs`), e.g.
  ``RSN6_IMPVALL.I_I-ELC180.AT2+RSN6_IMPVALL.I_I-ELC270.AT2+RSN6_IMPVALL.I_I-ELC-UP.AT2``
  (a path containing ``+`` is read as one file when that file exists);
* for `load_records` only, a bare suite name: ``fema-farfield`` (44), ``fema-nearfield`` (56), ``fema``
  (both, 100 horizontal components) or ``library`` (every library record).

A record file's component must fit its place (`component`): a file that holds a vertical component is
refused as a horizontal one (alone or in ``H1+H2``) unless ``accept_vertical`` (``--accept-vertical``) says
that it is meant to drive surge alone; a horizontal one is refused in the ``UP`` place. SEED channel codes
with their location codes (``BHZ00``, ``….BHZ.00.AT2``, CSV columns ``HN1``/``HN2``/``HNZ``) name it in every
format; an unknown component (COSMOS "Other", a plain text file, a bare ``acc`` column, a PEER line 2 that names
none) is read with a `RecordWarning`.

Only a regular file of at most 64 MiB is read (FIFOs and devices, also behind a symlink, are refused unread),
with a time step of 10 µs to 1 s and at most 1200 s long (`source`).

``dt`` [s] and ``units`` (``--dt``, ``--units`` on the CLI) are for record files that do not say them;
where a file does, they must agree with it; suites and library records refuse them. Every record comes
back as a `GroundMotion` (dt in s, acceleration in g).
"""

from __future__ import annotations

import difflib
from pathlib import Path

from .component import RecordWarning
from .cosmos import read_cosmos
from .csvfile import read_csv
from .fema import SUITES, load_suite, load_suite_record, suite_names
from .files import FILE_SUFFIXES, read_record_file
from .h5record import SCHEMA, read_h5, write_record
from .library import (
    ENV_VAR,
    Imported,
    default_library_dir,
    import_records,
    library_dir,
    library_names,
    load_library,
    load_library_record,
)
from .motion import G, GroundMotion, RecordError
from .pairs import read_components, read_file_spec, split_components
from .peer import read_at2
from .text import read_text

#: Names that stand for several suites at once.
SUITE_ALIASES: dict[str, tuple[str, ...]] = {"fema": SUITES}

#: The suite name of the user's record library (``library:NAME``; ``library`` in `load_records`).
LIBRARY = "library"

__all__ = [
    "ENV_VAR",
    "FILE_SUFFIXES",
    "LIBRARY",
    "SCHEMA",
    "SUITES",
    "SUITE_ALIASES",
    "G",
    "GroundMotion",
    "Imported",
    "RecordError",
    "RecordWarning",
    "default_library_dir",
    "expand_suite",
    "import_records",
    "library_dir",
    "library_names",
    "load_library",
    "load_library_record",
    "load_record",
    "load_records",
    "load_suite",
    "load_suite_record",
    "read_at2",
    "read_components",
    "read_cosmos",
    "read_csv",
    "read_file_spec",
    "read_h5",
    "read_record_file",
    "read_text",
    "suite_names",
    "write_record",
]


def expand_suite(name: str) -> tuple[str, ...] | None:
    """The suites a name stands for (a suite or an alias such as ``fema``), or None if it is neither."""
    if name in SUITES:
        return (name,)
    return SUITE_ALIASES.get(name)


def _spec_help() -> str:
    suites = ", ".join((*SUITES, *SUITE_ALIASES, LIBRARY))
    readable = ", ".join(FILE_SUFFIXES)
    return (
        f"expected SUITE:NAME (suites: {suites}; names: `rig records list SUITE`), "
        f"a record file ({readable}) or H1+H2[+UP]"
    )


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


def _refuse_file_options(spec: str, dt: float | None, units: str | None) -> None:
    """dt and units describe record files; a suite or library record has its own."""
    if dt is not None or units is not None:
        raise RecordError(f"{spec!r} has its own dt and units; expected dt/units only with a record file")


def _load_file(spec: str, dt: float | None, units: str | None, accept_vertical: bool) -> GroundMotion:
    """A record file by path or an ``H1+H2[+UP]`` component set."""
    if split_components(spec) is None and not Path(spec).expanduser().exists():
        raise RecordError(f"{spec!r} is neither a record nor an existing file (no such file); {_spec_help()}")
    return read_file_spec(spec, dt=dt, units=units, accept_vertical=accept_vertical)


def load_record(
    spec: str,
    *,
    dt: float | None = None,
    units: str | None = None,
    library: str | Path | None = None,
    accept_vertical: bool = False,
) -> GroundMotion:
    """One record from a spec (see the module docstring).

    Args:
        spec: ``SUITE:NAME``, ``library:NAME``, a record file or ``H1+H2[+UP]``.
        dt: time step [s] of a record file that does not give one.
        units: acceleration unit of a record file that does not give one (``g``, ``cm/s/s``, ``m/s/s``, …).
        library: the record library directory (default: `library_dir`).
        accept_vertical: a record file that holds only a vertical component may drive surge alone (refused
            otherwise, see `component.check_place`).
    """
    spec = spec.strip()
    if not spec:
        raise RecordError(f"empty record spec; {_spec_help()}")
    if spec == LIBRARY:
        count = len(library_names(library))
        raise RecordError(
            f"{spec!r} is the record library ({count} records), not one record; use library:NAME "
            "(names: `rig records list library`)"
        )
    if expand_suite(spec) is not None:
        count = sum(len(suite_names(s)) for s in expand_suite(spec) or ())
        raise RecordError(
            f"{spec!r} is a suite of {count} records, not one record; use {spec}:NAME "
            f"(names: `rig records list {spec}`)"
        )
    prefix, sep, name = spec.partition(":")
    if sep and prefix == LIBRARY:
        if not name:
            raise RecordError(f"{spec!r}: missing record name after ':'; {_spec_help()}")
        _refuse_file_options(spec, dt, units)
        return load_library_record(name, library)
    suites = expand_suite(prefix) if sep else None
    if suites is not None:
        if not name:
            raise RecordError(f"{spec!r}: missing record name after ':'; {_spec_help()}")
        _refuse_file_options(spec, dt, units)
        return _load_from_suites(suites, name, spec)
    if sep and _looks_like_suite(prefix) and not Path(spec).exists():
        valid = ", ".join((*SUITES, *SUITE_ALIASES, LIBRARY))
        raise RecordError(f"unknown record suite {prefix!r} in {spec!r}; valid suites: {valid}")
    return _load_file(spec, dt, units, accept_vertical)


def load_records(
    spec: str,
    *,
    dt: float | None = None,
    units: str | None = None,
    library: str | Path | None = None,
    accept_vertical: bool = False,
) -> list[GroundMotion]:
    """All records a spec names: a whole suite (``fema-farfield``, ``fema-nearfield``, ``fema``), the whole
    ``library``, or one record (`load_record`)."""
    name = spec.strip()
    if name == LIBRARY:
        _refuse_file_options(name, dt, units)
        return load_library(library)
    suites = expand_suite(name)
    if suites is not None:
        _refuse_file_options(name, dt, units)
        return [motion for suite in suites for motion in load_suite(suite)]
    return [load_record(spec, dt=dt, units=units, library=library, accept_vertical=accept_vertical)]
