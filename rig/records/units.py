"""Acceleration units of record files and their factors to g (g = 9.81 m/s², `motion.G`).

Understood (case-insensitive; ``sec`` = ``s``; ``/s/s`` = ``/s^2`` = ``/s2`` = ``/s**2`` = ``/s²`` = `` s-2``;
``/`` may also be written ``_`` as in a CSV column name ``acc_cm_s2``):

* ``g`` — standard gravity;
* ``gal`` or ``cm/s/s`` — centimetres per second squared (1 gal = 0.01 m/s²);
* ``m/s/s`` — metres per second squared;
* ``mm/s/s`` — millimetres per second squared.
"""

from __future__ import annotations

import re

from .motion import G, RecordError

#: Factor from each canonical unit to g.
TO_G: dict[str, float] = {"g": 1.0, "cm/s/s": 0.01 / G, "m/s/s": 1.0 / G, "mm/s/s": 0.001 / G}

#: The unit list quoted in error messages.
UNIT_HELP = "g, cm/s/s (= gal, cm/s^2), m/s/s (m/s^2), mm/s/s"

#: Spellings after `_squash`, mapped to the canonical unit.
_SPELLINGS: dict[str, str] = {
    "g": "g",
    "gal": "cm/s/s",
    "cms2": "cm/s/s",
    "ms2": "m/s/s",
    "mms2": "mm/s/s",
}


def _squash(text: str) -> str:
    """Lower case without spaces and separators: ``CM/SEC/SEC`` → ``cms2``, ``m s^-2`` → ``ms2``."""
    text = text.strip().lower().replace("²", "2").replace("sec", "s")
    text = re.sub(r"[\s/_^*]", "", text)
    text = re.sub(r"s-?2$", "s2", text)
    return re.sub(r"ss$", "s2", text)


def parse_unit(text: str) -> str | None:
    """The canonical name (a key of `TO_G`) of an acceleration unit as written, or None if unknown."""
    return _SPELLINGS.get(_squash(text))


def given_unit(text: str | None) -> str | None:
    """The canonical unit the user gave (``--units``), None if none was given; `RecordError` if unknown."""
    if text is None:
        return None
    unit = parse_unit(text)
    if unit is None:
        raise RecordError(f"unknown acceleration unit {text!r}; expected one of {UNIT_HELP}")
    return unit
