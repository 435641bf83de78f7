"""Which component a record file holds — horizontal, vertical or unknown — and where it may be used.

A record's place decides the table axis it drives: ``acc_h`` surge, ``acc_h2`` sway, ``acc_v`` heave. A
vertical channel played as a horizontal one (or the reverse) is a silent swap, so the readers report what
the file says about its component, in the provenance key ``component``::

    {"kind": "vertical", "said_by": "PEER line 2 component 'UP'", "line": 2}

``kind`` is ``"horizontal"``, ``"vertical"`` or ``"unknown"`` (the file does not say, or says "other").
Sources, by format:

* COSMOS: the orientation code (integer-header value 54) of the channel: azimuth 1-360 → horizontal,
  400 Up / 401 Down / 402 vertical → vertical, 500/501/600/601/700/701 → horizontal, 2000 "Other", 0 or
  the file's unknown marker → unknown: then the file name of a one-channel file (``NP.7010.00.HNZ.V2``),
  else a warning;
* PEER ``.AT2``: the component after the last comma of header line 2 (``230``, ``UP``, ``DWN``, ``V``, a
  SEED channel code with or without its location code, ``HNZ``, ``HN1``, ``BHZ00``, ``HNZ.10``, ``00.HNZ``),
  and the file name (``…-UP.AT2``, ``…DWN.AT2``, ``…HNZ.AT2``, ``….BHZ.00.AT2``);
* plain text: the file name (as for PEER: ``….HNZ.txt``, ``CI.PAS.00.HNZ.txt``, ``…-UP.txt``);
* CSV: the column names (``acc_h``, ``acc_h2``, ``acc_v`` or SEED channel codes such as ``HN1_g``), or for a
  lone ``acc`` column the file name;
* the project's ``.h5`` record: the component its source file gave, kept in its provenance.

A SEED channel code (SEED manual, appendix A) is three characters: the band (sample rate and response:
``H``, ``B``, ``E``, ``S``, ``L``, …), the instrument (``N`` accelerometer, ``H``/``L`` seismometer, ``G``
gravimeter) and the orientation: ``Z`` vertical; ``N``, ``E`` horizontal; ``1``, ``2`` horizontal at an
azimuth the metadata gives, with ``3`` the vertical of that orthogonal set (NGA-East's ``HN1``, ``HN2``,
``HNZ``); ``T``, ``R`` transverse and radial (horizontal). ``A``, ``B``, ``C`` (a triaxial set on a cube's
corner) and ``U``, ``V``, ``W`` are neither: unknown. A location code is two digits (``00``, ``10``) or
``--``, written before or after the channel, joined by ``.``, ``_``, ``-`` or nothing (``BHZ00``).

Whenever the component of a one-component record is unknown, its reader issues a `RecordWarning` naming the
file (and the line that was read for it): the record is played as a horizontal one only after the user has
been told.

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
#: SEED band, instrument and orientation codes (module docstring) and a location code.
_BAND, _INSTRUMENT, _ORIENTATION = "FGDCESHBMLVURPTQ", "HLGN", "ZNE123TRABCUVW"
_CHANNEL = rf"(?P<band>[{_BAND}])(?P<instrument>[{_INSTRUMENT}])(?P<orientation>[{_ORIENTATION}])"
_LOCATION = r"(?:\d[\dA-Z]|--)"
#: A SEED channel code alone or with its location code before or after it (``HNZ``, ``BHZ00``, ``00.HNZ``).
_SEED_WORD_RE = re.compile(
    rf"(?:(?P<before>{_LOCATION})[._\- ]?)?{_CHANNEL}(?:[._\- ]?(?P<after>{_LOCATION}))?", re.I
)
#: … at the end of a file stem after a separator (``CI.PAS.00.HNZ``, ``RSN1_X.BHZ.00``, ``ST01_HN1``): the
#: location before the channel (NET.STA.LOC.CHA, as FDSN names its files) or after it.
_SEED_STEM_RE = re.compile(
    rf"(?:^|[._\-])(?:(?P<before>{_LOCATION})[._\-])?{_CHANNEL}(?:[._\-](?P<after>{_LOCATION}))?$", re.I
)
_SEED_KINDS = {"Z": VERTICAL, "3": VERTICAL, "N": HORIZONTAL, "E": HORIZONTAL, "1": HORIZONTAL, "2": HORIZONTAL,
               "T": HORIZONTAL, "R": HORIZONTAL}
_SEED_ORIENTATIONS = {"Z": "vertical", "3": "the third of an orthogonal set, vertical", "N": "north", "E": "east",
                      "1": "horizontal 1", "2": "horizontal 2", "T": "transverse", "R": "radial"}

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


def _seed(match: re.Match[str] | None) -> tuple[str, str] | None:
    """(kind, description) of a matched SEED channel code, or None when there is no match."""
    if match is None:
        return None
    band, instrument, orientation = (match[k].upper() for k in ("band", "instrument", "orientation"))
    location = match.groupdict().get("before") or match["after"]
    code = band + instrument + orientation + (f" location {location}" if location else "")
    meaning = _SEED_ORIENTATIONS.get(orientation, "not a horizontal or vertical orientation")
    return _SEED_KINDS.get(orientation, UNKNOWN), f"SEED channel {code}: orientation {orientation}, {meaning}"


def seed_word(word: str) -> tuple[str, str] | None:
    """(kind, description) of a SEED channel code with or without its location (``BHZ00``), or None."""
    return _seed(_SEED_WORD_RE.fullmatch(word.strip().strip(".")))


def name_component(path: str | Path) -> tuple[str, str] | None:
    """(kind, what the name says) from a file name (a SEED channel code or ``-UP``, ``DWN``… at the end of its
    stem), or None if the name does not say."""
    name = Path(path).name
    found = _seed(_SEED_STEM_RE.search(Path(path).stem))
    if found is not None and found[0] != UNKNOWN:
        return found[0], f"the file name {name!r}, {found[1]}"
    if stem_says_vertical(path):
        return VERTICAL, f"the file name {name!r}"
    return None


def from_name(path: str | Path, what: str) -> dict[str, Any]:
    """The component of a file that says nothing about it but ``what`` (e.g. "a plain text file names no
    component"): from its name, else unknown with a `RecordWarning`."""
    named = name_component(path)
    if named is not None:
        return component(named[0], named[1])
    return unknown_component(path, None, f"{what} and the file name does not say")


def unknown_component(path: str | Path, line: int | None, said_by: str) -> dict[str, Any]:
    """An unknown component: the provenance entry, after a `RecordWarning` that says so."""
    where = f"{path}:{line}" if line else f"{path}"
    warn(f"{where}: the component (horizontal or vertical) is unknown: {said_by}; it is played as a horizontal "
         "one, check it before playing it")
    return component(UNKNOWN, said_by, line)


def classify_word(word: str) -> str:
    """Kind of a PEER/NGA component word: ``horizontal``, ``vertical`` or ``unknown``."""
    word = word.strip().strip(".")
    seed = seed_word(word)
    if seed is not None:
        return seed[0]
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
    named = name_component(path)
    from_name, name_says = named if named is not None else (UNKNOWN, "")
    if {from_line, from_name} == {HORIZONTAL, VERTICAL}:
        raise RecordError(
            f"{path}:2: line 2 gives the {from_line} component {word!r} but the file name {path.name!r} names a "
            f"{from_name} one; expected the two to agree (rename the file or fix line 2)"
        )
    if from_line != UNKNOWN:
        seed = seed_word(word)
        said = f", {seed[1]}" if seed is not None else ""
        return component(from_line, f"PEER line 2 component {word!r}{said}", 2)
    if from_name != UNKNOWN:
        return component(from_name, name_says)
    said = f"line 2 gives {word!r}, not a component" if word else "line 2 gives no component after a comma"
    return unknown_component(path, 2, f"{said} and the file name does not say")


def kind_of_provenance(provenance: dict[str, Any]) -> str:
    """The component kind a one-component record's provenance gives (``unknown`` if none)."""
    entry = provenance.get("component")
    kind = entry.get("kind", UNKNOWN) if isinstance(entry, dict) else UNKNOWN
    return kind if kind in (HORIZONTAL, VERTICAL) else UNKNOWN


def kind_of(motion: GroundMotion) -> str:
    """The component kind a one-component record's provenance gives (``unknown`` if none)."""
    return kind_of_provenance(motion.provenance)


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
