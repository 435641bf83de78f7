"""The user's record library: a directory of the project's record files, one per imported record.

Where it is, first that applies:

1. the directory the caller passes (``--library DIR`` on the CLI);
2. the environment variable ``RIG_RECORD_LIBRARY``;
3. the platform's user data directory: ``$XDG_DATA_HOME/shaketable-rig/records`` (an absolute
   ``XDG_DATA_HOME`` only), else ``~/.local/share/shaketable-rig/records``; on macOS
   ``~/Library/Application Support/shaketable-rig/records``; on Windows
   ``%LOCALAPPDATA%\\shaketable-rig\\records`` (else ``~\\AppData\\Local\\shaketable-rig\\records``).

Each record is ``<file name>.h5`` (schema in `h5record`), the file name being the record's name with every
character other than letters, digits, blanks and ``_ . - + , = @`` percent-encoded (``NORTHR/MUL009`` →
``NORTHR%2FMUL009.h5``; a leading ``.`` too), so that any name maps to one safe file and back. Importing
reads the source file(s), never changes them, keeps their paths and checksums in the provenance and writes
the record atomically (`h5record.write_record`): a name that exists is refused unless ``replace``, and a
failed import leaves no partial file and the previous record intact. Load a record with ``library:NAME``.
On a case-insensitive file system (macOS, Windows) names that differ only in case share one file, so the
second of them is refused as existing.
"""

from __future__ import annotations

import dataclasses
import datetime
import difflib
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from urllib.parse import quote, unquote

from .h5record import read_h5, write_record
from .motion import GroundMotion, RecordError
from .pairs import read_file_spec

ENV_VAR = "RIG_RECORD_LIBRARY"
SUFFIX = ".h5"
#: Longest record name accepted [characters].
MAX_NAME = 120
#: Longest file name written [bytes] (most file systems allow 255).
MAX_FILE_NAME = 240
_SAFE = " _.-+,=@"


def default_library_dir() -> Path:
    """The platform's default library directory (see the module docstring)."""
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Application Support" / "shaketable-rig" / "records"
    if sys.platform == "win32":
        local = os.environ.get("LOCALAPPDATA", "")
        base = Path(local) if local else Path.home() / "AppData" / "Local"
        return base / "shaketable-rig" / "records"
    xdg = os.environ.get("XDG_DATA_HOME", "")
    base = Path(xdg) if xdg and Path(xdg).is_absolute() else Path.home() / ".local" / "share"
    return base / "shaketable-rig" / "records"


def library_dir(directory: str | Path | None = None) -> Path:
    """The library directory: ``directory``, else ``$RIG_RECORD_LIBRARY``, else `default_library_dir`."""
    if directory is not None and str(directory):
        return Path(directory).expanduser()
    env = os.environ.get(ENV_VAR, "")
    return Path(env).expanduser() if env else default_library_dir()


def check_name(name: str) -> str:
    """``name`` if it can name a library record: 1-120 printable characters, no outer blanks."""
    if not name or name != name.strip() or len(name) > MAX_NAME or not name.isprintable():
        raise RecordError(
            f"{name!r} cannot name a library record; expected 1-{MAX_NAME} printable characters "
            "without leading or trailing blanks"
        )
    return name


def file_name(name: str) -> str:
    """The file name of a library record (percent-encoded name + ``.h5``)."""
    encoded = quote(check_name(name), safe=_SAFE)
    if encoded.startswith("."):
        encoded = "%2E" + encoded[1:]
    if len(encoded) + len(SUFFIX) > MAX_FILE_NAME:
        raise RecordError(
            f"{name!r} is too long as a file name ({len(encoded) + len(SUFFIX)} bytes encoded); "
            f"expected at most {MAX_FILE_NAME} bytes"
        )
    return encoded + SUFFIX


def record_path(name: str, directory: str | Path | None = None) -> Path:
    """Where the library record ``name`` is (or would be) stored."""
    return library_dir(directory) / file_name(name)


def _entries(root: Path) -> dict[str, Path]:
    """Each record file of the library by record name (the decoded file name), sorted by name."""
    if not root.is_dir():
        return {}
    files = (p for p in root.glob(f"*{SUFFIX}") if p.is_file())
    return dict(sorted((unquote(p.name.removesuffix(SUFFIX)), p) for p in files))


def library_names(directory: str | Path | None = None) -> list[str]:
    """Names of the records in the library, sorted; an empty list if the directory does not exist."""
    return list(_entries(library_dir(directory)))


def load_library_record(name: str, directory: str | Path | None = None) -> GroundMotion:
    """The library record ``name`` (named so whatever name the file stores); `RecordError` if there is none."""
    root = library_dir(directory)
    entries = _entries(root)
    if name not in entries:
        close = difflib.get_close_matches(name, list(entries), n=3)
        hint = f" Did you mean: {', '.join(close)}?" if close else ""
        raise RecordError(
            f"no record {name!r} in the library {root}.{hint} List them with `rig records list library`."
        )
    return _load(name, entries[name])


def _load(name: str, path: Path) -> GroundMotion:
    """A library record file, named by its library name."""
    motion = read_h5(path)
    return motion if motion.name == name else dataclasses.replace(motion, name=name)


def load_library(directory: str | Path | None = None) -> list[GroundMotion]:
    """Every record in the library, sorted by name."""
    return [_load(name, path) for name, path in _entries(library_dir(directory)).items()]


@dataclasses.dataclass(frozen=True)
class Imported:
    """A record stored in the library by `import_records`."""

    name: str
    path: Path
    motion: GroundMotion
    replaced: bool


def import_records(
    sources: Sequence[str],
    *,
    name: str | None = None,
    dt: float | None = None,
    units: str | None = None,
    directory: str | Path | None = None,
    replace: bool = False,
    accept_vertical: bool = False,
) -> list[Imported]:
    """Read each source (a record file or ``H1+H2[+UP]``) and store it in the library.

    Every source is read and every name checked before anything is written, so a bad file or a taken
    name stores nothing. Each record is named ``name`` (one source only) or after its source (file stem,
    or the stems joined by ``+``); its provenance gains ``imported`` (UTC, ISO 8601). A file that holds only a
    vertical component is refused unless ``accept_vertical`` (`rig.records.component.check_place`).
    """
    if not sources:
        raise RecordError("nothing to import; expected a record file or H1+H2[+UP]")
    if name is not None and len(sources) != 1:
        raise RecordError(f"a name was given for {len(sources)} records; expected one record with a name")
    root = library_dir(directory)
    motions = [read_file_spec(spec, dt=dt, units=units, accept_vertical=accept_vertical) for spec in sources]
    names = [check_name(name if name is not None else m.name) for m in motions]
    paths = [record_path(n, root) for n in names]
    for i, path in enumerate(paths):
        if path in paths[:i]:
            raise RecordError(f"two of the records to import are named {names[i]!r}; expected distinct names")
        if path.exists() and not replace:
            raise RecordError(
                f"the library {root} already has a record {names[i]!r} ({path.name}); "
                "expected a new name (--name) or --replace to replace it"
            )
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RecordError(f"{root}: cannot create the library directory ({exc.strerror or exc})") from None
    stamp = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    imported: list[Imported] = []
    for record_name, path, motion in zip(names, paths, motions, strict=True):
        stored = GroundMotion(
            name=record_name, dt=motion.dt, acc_h=motion.acc_h, acc_h2=motion.acc_h2, acc_v=motion.acc_v,
            provenance={**motion.provenance, "imported": stamp},
        )
        existed = path.exists()
        write_record(stored, path, replace=replace)
        imported.append(Imported(name=record_name, path=path, motion=stored, replaced=existed))
    return imported
