"""The checks every TOML file of the rig shares: tables with known keys, numbers, and errors that name the key.

:class:`TomlChecker` is the base of the rig configuration's reader (``analysis.table.model``) and the sequence
file's (``rig.sequence.reader``): it walks a mapping that ``tomllib`` parsed, by key paths (``KeyPath``), and
raises the reader's own error (:meth:`TomlChecker.error`), which finds the key's line with
:func:`~analysis.table.toml_lines.find_line`. What a value must be beyond "a table" and "a number" (units,
ranges, choices) is each reader's; :meth:`TomlChecker.ranged` checks a number against its physical range.

:func:`read_toml` reads the file for both: only a regular file of at most `MAX_TOML_BYTES` (a FIFO, a device
or a symlink to one is refused before a byte is read, `analysis.input_file`), UTF-8 text, and arrays or
tables nested at most as deeply as Python's parser can follow (5,000 nested ``[`` is a syntax error, not a
crash).
"""

from __future__ import annotations

import math
import numbers
import reprlib
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, TypeGuard

import numpy as np

from analysis.input_file import MIB, InputFileError, read_regular_file
from analysis.table.toml_lines import KeyPath, find_line, key_lines, suggest, syntax_message

MAX_TOML_BYTES = 1 * MIB
"""Largest sequence or rig configuration file read [bytes] (the paper's campaign is 5 kB)."""

_SHOWN = reprlib.Repr()
_SHOWN.maxstring = _SHOWN.maxother = 60
_SHOWN.maxlist = _SHOWN.maxdict = 6


def shown(value: object) -> str:
    """``repr(value)`` cut to a readable length for an error message (a 1 MB string or list is not echoed)."""
    return _SHOWN.repr(value)


class TomlFileError(ValueError):
    """A TOML file that cannot be read or parsed: ``line`` (1-based, or None) and ``problem`` (no file name)."""

    def __init__(self, line: int | None, problem: str) -> None:
        super().__init__(problem)
        self.line, self.problem = line, problem


def read_toml(path: str | Path, expected: str) -> tuple[dict[str, Any], dict[KeyPath, int]]:
    """The parsed mapping and the key lines (`key_lines`) of a TOML file.

    Raises:
        TomlFileError: not a regular file of at most `MAX_TOML_BYTES`, not UTF-8, or a TOML syntax error
            (with its line), including arrays nested too deeply to parse.
    """
    source = str(path)
    try:
        raw = read_regular_file(path, MAX_TOML_BYTES, expected)
    except InputFileError as exc:
        raise TomlFileError(None, str(exc)) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        byte = raw[exc.start]
        raise TomlFileError(line, f"byte 0x{byte:02x} is not UTF-8 text; expected {expected} in UTF-8") from None
    try:
        data = tomllib.loads(text)
        lines = key_lines(text)
    except RecursionError:
        raise TomlFileError(None, "TOML syntax error: arrays or tables nested too deeply to parse; expected at "
                                  "most a few levels") from None
    except tomllib.TOMLDecodeError as exc:
        message = syntax_message(source, text, str(exc)).removeprefix(f"{source}")
        number, _, problem = message.removeprefix(":").partition(": ")
        if number.isdigit():
            raise TomlFileError(int(number), problem) from None
        raise TomlFileError(None, message.removeprefix(": ")) from None
    return data, lines


def is_number(value: object) -> TypeGuard[numbers.Real]:
    """A real number as TOML (or a caller's mapping) gives one: int or float, not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)


class TomlChecker:
    """Checks values of the mapping read from ``source``; ``lines`` (``key_lines`` of its text, or empty for a
    mapping without a text) give each key's line. Subclasses define :meth:`error`."""

    def __init__(self, source: str, lines: Mapping[KeyPath, int]) -> None:
        self.source = source
        self.lines = lines

    def line(self, path: KeyPath) -> int | None:
        """The line of ``path``, else of the first key or header under it, else of its nearest parent."""
        return find_line(self.lines, path)

    def error(self, path: KeyPath, problem: str) -> Exception:
        """The error to raise for ``problem`` at the key ``path`` (the subclass's exception type)."""
        raise NotImplementedError

    def unknown_key_hint(self, path: KeyPath, key: str, allowed: Sequence[str]) -> str:
        """Text after "unknown key" for ``key`` under ``path``: by default the closest allowed key."""
        return suggest(key, allowed)

    def table(self, value: Any, path: KeyPath, allowed: Sequence[str]) -> Mapping[str, Any]:
        """``value`` checked to be a table whose keys are all in ``allowed``."""
        if not isinstance(value, Mapping):
            raise self.error(path, f"expected a table, got {shown(value)}")
        for key in value:
            if key not in allowed:
                raise self.error((*path, key), f"unknown key{self.unknown_key_hint(path, key, allowed)}; expected "
                                               f"one of {', '.join(allowed)}")
        return value

    def real(self, value: Any, path: KeyPath, what: str = "a number") -> float:
        """``value`` as a float, if it is a number (any: the caller checks its range)."""
        if not is_number(value):
            raise self.error(path, f"expected {what}, got {shown(value)}")
        try:
            return float(value)
        except OverflowError:
            raise self.error(path, f"expected {what}, got {shown(value)}") from None

    def ranged(self, value: Any, path: KeyPath, low: float, high: float, what: str) -> float:
        """A number in its physical range ``[low, high]``; ``what`` says the range in words with the unit, e.g.
        ``"a time from 0 s to 60 s"``."""
        x = self.real(value, path, what)
        if not (math.isfinite(x) and low <= x <= high):
            raise self.error(path, f"expected {what}, got {shown(value)}")
        return x
