"""Record files by suffix (any case): one reader per format, each returning a `GroundMotion` [g, s].

* ``.at2`` — PEER NGA acceleration file, NGA-West2 or older NGA header (`peer.read_at2`);
* ``.txt``, ``.dat``, ``.acc`` — plain text, one or two columns: time, acceleration (`text.read_text`);
* ``.csv`` — CSV with a header row naming the columns (`csvfile.read_csv`);
* ``.h5``, ``.hdf5`` — the project's own record file, schema shaketable-rig/record/1 (`h5record.read_h5`);
* ``.v1``, ``.v2``, ``.v1c``, ``.v2c`` — COSMOS strong-motion file (format v01.20) as CESMD and the USGS
  distribute them, V1 uncorrected or V2 corrected acceleration, one channel or two horizontal and an optional vertical
  (`cosmos.read_cosmos`).

``dt`` [s] and ``units`` are for files that do not say them; where a file does, they must agree with it.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from .cosmos import read_cosmos
from .csvfile import read_csv
from .h5record import read_h5
from .motion import GroundMotion
from .peer import read_at2
from .source import located
from .text import read_text

_Reader = Callable[..., GroundMotion]

#: Reader of each file suffix (lower case).
READERS: dict[str, _Reader] = {
    ".at2": read_at2,
    ".txt": read_text,
    ".dat": read_text,
    ".acc": read_text,
    ".csv": read_csv,
    ".h5": read_h5,
    ".hdf5": read_h5,
    ".v1": read_cosmos,
    ".v2": read_cosmos,
    ".v1c": read_cosmos,
    ".v2c": read_cosmos,
}

#: File suffixes (lower case) with a reader.
FILE_SUFFIXES: tuple[str, ...] = tuple(READERS)


def read_record_file(path: str | Path, *, dt: float | None = None, units: str | None = None) -> GroundMotion:
    """Read a record file with the reader for its suffix (see the module docstring)."""
    path = Path(path).expanduser()
    reader = READERS.get(path.suffix.lower())
    if reader is None:
        readable = ", ".join(FILE_SUFFIXES)
        raise located(path, None, f"unsupported record file type {path.suffix!r}; expected one of {readable}")
    return reader(path, dt=dt, units=units)
