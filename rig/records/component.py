"""Which component a record file holds — horizontal, vertical or unknown — and where it may be used.

A record's place decides the table axis it drives: ``acc_h`` surge, ``acc_h2`` sway, ``acc_v`` heave. A
vertical channel played as a horizontal one (or the reverse) is a silent swap, so the readers report what
the file says about its component, in the provenance key ``component``::

    {"kind": "vertical", "said_by": "PEER line 2 component 'UP'", "line": 2}

``kind`` is ``"horizontal"``, ``"vertical"`` or ``"unknown"`` (the file does not say, or says "other").
Sources, by format:

* COSMOS: the orientation code (integer-header value 54) of the channel: azimuth 1-360 → horizontal,
  400 Up / 401 Down / 402 vertical → vertical, 500/501/600/601/700/701 → horizontal, 2000 "Other", 0 or
  the file's unknown marker → unknown, with a warning;
* PEER ``.AT2``: the component after the last comma of header line 2 (``230``, ``UP``, ``DWN``, ``V``, the
  NGA-East channel name ``HNZ``/``HN1``…), and the file name (``…-UP.AT2``, ``…DWN.AT2``, ``…HNZ.AT2``);
* other formats do not say (``unknown``, no warning: plain text and CSV files carry no orientation).

`check_place` refuses a vertical in a horizontal place, a horizontal in the vertical place, and a lone
vertical unless the caller accepts it (``accept_vertical``, ``--accept-vertical`` on the CLI).
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path
from typing import Any

from .motion import GroundMotion, RecordError

HORIZONTAL, VERTICAL, UNKNOWN = "horizontal", "vertical", "unknown"

#: Component words of PEER/NGA files that mean vertical (any case): PEER's UP, DWN (down), V, and the
#: SEED/NGA-East orientation code Z at the end of a channel name (``HNZ``, ``HHZ``, ``BNZ``).
_VERTICAL_WORD_RE = re.compile(r"^(?:UP|DWN|DN|DOWN|V|VER|VERT|VERTICAL|Z|[A-Z]{2}Z)$", re.I)
#: … and horizontal: an azimuth (``230``, ``360``), compass directions (``N00E``, ``S45W``, ``NS``, ``EW``,
#: ``E``), PEER's ``L``/``T``/``FN``/``FP``/``H1``/``H2``, SEED channel names ending in N, E, 1, 2.
_HORIZONTAL_WORD_RE = re.compile(
    r"^(?:\d{1,3}|[NS]\d{1,2}[EW]|[NSEW]|NS|EW|SN|WE|L|T|LN|TR|FN|FP|H1|H2|HOR|[A-Z]{2}[NE12])$", re.I
)
#: The end of a file stem that names a vertical component: ``-UP``, ``_V``, ``.DWN``, ``-DN``, ``UP``,
#: ``DWN``, and a channel name ending in Z after a separator (``.HNZ``, ``_HHZ``).
_VERTICAL_STEM_RE = re.compile(r"(?:[-_.](?:UP|V|DWN|DN|[A-Z]{2}Z)|UP|DWN)$", re.I)


class RecordWarning(UserWarning):
    """A record was read, but something about it deserves the user's attention (e.g. an unknown orientation)."""


def warn(message: str) -> None:
    """Issue a `RecordWarning` (the CLI prints it as ``warning: …`` on stderr)."""
    warnings.warn(message, RecordWarning, stacklevel=3)


def component(kind: str, said_by: str, line: int | None = None) -> dict[str, Any]:
    """The provenance entry ``component``."""
    return {"kind": kind, "said_by": said_by, "line": line}


def classify_word(word: str) -> str:
    """Kind of a PEER/NGA component word: ``horizontal``, ``vertical`` or ``unknown``."""
    word = word.strip().strip(".")
    if _VERTICAL_WORD_RE.match(word):
        return VERTICAL
    if _HORIZONTAL_WORD_RE.match(word):
        return HORIZONTAL
    return UNKNOWN


def stem_says_vertical(path: str | Path) -> bool:
    """True if the file name (without suffix) ends like a vertical component (``-UP``, ``DWN``, ``.HNZ`` …)."""
    return bool(_VERTICAL_STEM_RE.search(Path(path).stem))


def peer_component(line2: str, path: Path) -> dict[str, Any]:
    """The component of a PEER ``.AT2`` from header line 2 (the word after its last comma) and the file name.

    Line 2 and the name must not contradict each other (one vertical, the other horizontal): that is refused.
    """
    word = line2.rsplit(",", 1)[-1].strip() if "," in line2 else ""
    from_line = classify_word(word) if word else UNKNOWN
    from_name = VERTICAL if stem_says_vertical(path) else UNKNOWN
    if {from_line, from_name} == {HORIZONTAL, VERTICAL}:
        raise RecordError(
            f"{path}:2: line 2 gives the horizontal component {word!r} but the file name {path.name!r} names a "
            "vertical one; expected the two to agree (rename the file or fix line 2)"
        )
    if from_line != UNKNOWN:
        return component(from_line, f"PEER line 2 component {word!r}", 2)
    if from_name == VERTICAL:
        return component(VERTICAL, f"the file name {path.name!r}")
    return component(UNKNOWN, "neither line 2 nor the file name names the component")


def kind_of(motion: GroundMotion) -> str:
    """The component kind a one-component record's provenance gives (``unknown`` if none)."""
    entry = motion.provenance.get("component")
    return str(entry.get("kind", UNKNOWN)) if isinstance(entry, dict) else UNKNOWN


def _where(path: str | Path, motion: GroundMotion) -> str:
    """``FILE:LINE`` of the line that says which component the file holds (``FILE`` if no line does)."""
    entry = motion.provenance.get("component") or {}
    return f"{path}:{entry['line']}" if entry.get("line") else f"{path}"


def _holds(motion: GroundMotion) -> str:
    """E.g. ``a vertical component (COSMOS orientation code 400: Up, chan 1)``."""
    entry = motion.provenance.get("component") or {}
    return f"a {entry.get('kind', UNKNOWN)} component ({entry.get('said_by', '?')})"


def check_place(path: str | Path, motion: GroundMotion, place: str, *, accept_vertical: bool = False) -> None:
    """Refuse a one-component record in the wrong place.

    Args:
        path: the file (named in the error).
        motion: what its reader returned (``provenance["component"]`` as this module describes).
        place: ``"h"``/``"h2"`` (first/second horizontal of ``H1+H2[+UP]``), ``"v"`` (the vertical of
            ``H1+H2+UP``) or ``"alone"`` (the whole record, driving surge).
        accept_vertical: the user says a lone vertical component may drive the record (``place="alone"``).
    """
    kind, where, holds = kind_of(motion), _where(path, motion), _holds(motion)
    if place in ("h", "h2") and kind == VERTICAL:
        which = "first" if place == "h" else "second"
        raise RecordError(
            f"{where}: holds {holds}, given as the {which} horizontal of H1+H2[+UP]; expected a horizontal "
            "component there (put the vertical last: H1+H2+UP)"
        )
    if place == "v" and kind == HORIZONTAL:
        raise RecordError(
            f"{where}: holds {holds}, given as the vertical of H1+H2+UP; expected a vertical component "
            "there (UP, DWN, V, …Z)"
        )
    if place == "alone" and kind == VERTICAL and not accept_vertical:
        raise RecordError(
            f"{where}: holds {holds}; expected a horizontal record to drive surge. Give it as the vertical "
            "of H1+H2+UP, or play it alone on purpose with --accept-vertical (load_record(..., accept_vertical=True))"
        )
