"""Record files by suffix (any case): one reader per format, each returning a `GroundMotion` [g, s].

* ``.at2`` — PEER NGA acceleration file, NGA-West2 or older NGA header (`peer.read_at2`);
* ``.txt``, ``.dat``, ``.acc`` — plain text, one or two columns: time, acceleration (`text.read_text`);
* ``.csv`` — CSV with a header row naming the columns (`csvfile.read_csv`);
* ``.h5``, ``.hdf5`` — the project's own record file, schema shaketable-rig/record/1 (`h5record.read_h5`);
* ``.v1``, ``.v2``, ``.v1c``, ``.v2c`` — COSMOS strong-motion file (format v01.20) as CESMD and the USGS
  distribute them, V1 uncorrected or V2 corrected acceleration, one channel or two horizontal and an optional vertical
  (`cosmos.read_cosmos`).

``dt`` [s] and ``units`` are for files that do not say them; where a file does, they must agree with it.

Every reader reads only a regular file of at most `source.MAX_FILE_BYTES` (a FIFO, a device or a symlink to
one is refused before a byte is read), accepts a time step from `source.DT_MIN_S` to `source.DT_MAX_S` and
accelerations up to `source.MAX_ABS_G`; a record longer than `source.MAX_DURATION_S` is refused here.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from .cosmos import read_cosmos
from .csvfile import read_csv
from .h5record import read_h5
from .motion import GroundMotion
from .peer import read_at2
from .source import MAX_DURATION_S, located
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
    motion = reader(path, dt=dt, units=units)
    if motion.duration > MAX_DURATION_S:
        raise located(
            path, None, f"the record lasts {motion.duration:.6g} s ({motion.npts} samples at dt = {motion.dt:g} s); "
            f"expected at most {MAX_DURATION_S:g} s (is dt right?)",
        )
    return motion
