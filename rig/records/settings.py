"""The ``# key = value`` settings that plain-text and CSV record files may carry.

A line whose first non-blank character is ``#`` is a comment. A comment ``# KEY = VALUE`` (or
``# KEY: VALUE``; the key in any case) with one of these keys is a setting; every other comment is free text:

* ``dt`` — the time step in seconds, optionally followed by ``s`` or ``sec``: ``# dt = 0.01 s``;
* ``units`` (or ``unit``) — the acceleration unit of the samples: ``# units = cm/s/s`` (spellings in `units`);
* ``npts`` — the number of samples, checked against the data, so that a truncated file is caught.

A setting given twice, or one whose value does not parse, is an error located at its line.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace

from .source import TextSource
from .units import UNIT_HELP, parse_unit

_SETTING_RE = re.compile(r"\s*#\s*(?P<key>dt|units?|npts)\s*[=:]\s*(?P<value>.*?)\s*", re.I)
_DT_VALUE_RE = re.compile(r"(?P<number>\S+?)\s*(?:s|sec|seconds?)?", re.I)
_KEYS = {"dt": "dt", "unit": "units", "units": "units", "npts": "npts"}


def is_comment(text: str) -> bool:
    """True for a comment line (first non-blank character ``#``)."""
    return text.lstrip().startswith("#")


@dataclass(frozen=True)
class Settings:
    """The settings found in a file, each with the line (1-based) that gave it; None where absent.

    Attributes:
        dt: time step [s].
        unit: canonical acceleration unit (a key of `units.TO_G`); ``unit_text`` as written.
        npts: number of samples the file declares.
    """

    dt: float | None = None
    dt_line: int | None = None
    unit: str | None = None
    unit_text: str | None = None
    unit_line: int | None = None
    npts: int | None = None
    npts_line: int | None = None


def read_settings(src: TextSource, numbered: Iterable[tuple[int, str]] | None = None) -> Settings:
    """The ``dt``, ``units`` and ``npts`` settings of ``src`` (see the module docstring), from its lines or from
    ``numbered`` (line number, text) pairs, e.g. only its comment lines."""
    values: dict[str, tuple[str, int]] = {}
    for lineno, text in enumerate(src.lines, start=1) if numbered is None else numbered:
        match = _SETTING_RE.fullmatch(text)
        if match is None:
            continue
        key = _KEYS[match["key"].lower()]
        if key in values:
            raise src.error(lineno, f"second '{key}' setting (line {values[key][1]} gave one); expected one")
        values[key] = (match["value"], lineno)
    settings = Settings()
    if "dt" in values:
        text, lineno = values["dt"]
        settings = replace(settings, dt=_dt_value(src, lineno, text), dt_line=lineno)
    if "units" in values:
        text, lineno = values["units"]
        unit = parse_unit(text)
        if unit is None:
            raise src.error(lineno, f"unknown acceleration unit {text!r}; expected one of {UNIT_HELP}")
        settings = replace(settings, unit=unit, unit_text=text, unit_line=lineno)
    if "npts" in values:
        text, lineno = values["npts"]
        if not re.fullmatch(r"[0-9]+", text) or int(text) == 0:
            raise src.error(lineno, f"npts {text!r} is not a positive whole number; expected e.g. '# npts = 4000'")
        settings = replace(settings, npts=int(text), npts_line=lineno)
    return settings


def _dt_value(src: TextSource, lineno: int, value: str) -> float:
    """The seconds of a ``dt`` setting's value (``0.01``, ``0.01 s``, ``1e-2 sec``)."""
    match = _DT_VALUE_RE.fullmatch(value)
    if match is None:
        raise src.error(lineno, f"dt {value!r} is not a time in seconds; expected e.g. '# dt = 0.01 s'")
    return src.check_dt(lineno, src.number(lineno, match["number"], "dt"), value)


def check_npts(src: TextSource, settings: Settings, lines: Sequence[int]) -> None:
    """Compare a ``# npts`` setting, if any, with the samples found on ``lines`` (one line number each)."""
    if settings.npts is not None and settings.npts != len(lines):
        kind = "truncated data" if len(lines) < settings.npts else "extra data"
        raise src.error(
            settings.npts_line,
            f"{kind}: npts = {settings.npts} but the file holds {len(lines)} samples "
            f"(lines {lines[0]}-{lines[-1]}); expected {settings.npts} samples",
        )
