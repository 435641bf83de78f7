"""The checks every TOML file of the rig shares: tables with known keys, numbers, and errors that name the key.

:class:`TomlChecker` is the base of the rig configuration's reader (``analysis.table.model``) and the sequence
file's (``rig.sequence.reader``): it walks a mapping that ``tomllib`` parsed, by key paths (``KeyPath``), and
raises the reader's own error (:meth:`TomlChecker.error`), which finds the key's line with
:func:`~analysis.table.toml_lines.find_line`. What a value must be beyond "a table" and "a number" (units,
ranges, choices) is each reader's.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from analysis.table.toml_lines import KeyPath, find_line, suggest


def is_number(value: object) -> bool:
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
            raise self.error(path, f"expected a table, got {value!r}")
        for key in value:
            if key not in allowed:
                raise self.error((*path, key), f"unknown key{self.unknown_key_hint(path, key, allowed)}; expected "
                                               f"one of {', '.join(allowed)}")
        return value

    def real(self, value: Any, path: KeyPath, what: str = "a number") -> float:
        """``value`` as a float, if it is a number (any: the caller checks its range)."""
        if not is_number(value):
            raise self.error(path, f"expected {what}, got {value!r}")
        return float(value)
