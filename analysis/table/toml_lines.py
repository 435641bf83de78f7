"""Where the keys of a TOML file are: line numbers for error messages ``FILE:LINE: key.path: problem``.

``tomllib`` gives values without positions; :func:`key_lines` scans the same text once more and returns the
1-based line of every table header, ``key =``, array element and inline-table key, by its full path. A path
is a tuple of keys (str) and array indices (int, from 0): ``("limits", "surge", "displacement_m")``,
``("bodies", 1, "h")`` for ``h`` in the second ``[[bodies]]`` table, ``("records", 2, "scale")`` for the
``scale`` of the third element of ``records = [...]``. :func:`dotted_path` writes such a path for people,
counting list items from 1: ``bodies[2].h``.

Used by the rig configuration (``analysis.table.model``) and the sequence files (``rig.sequence``). The
scanner expects text that ``tomllib`` has already accepted (call it after ``tomllib.loads``); on anything
it does not understand it stops and returns what it has found so far, so a message may then name a
parent's line instead.
"""

from __future__ import annotations

import bisect
import contextlib
import difflib
import re
import tomllib
from collections.abc import Iterable, Mapping

KeyPath = tuple[str | int, ...]
"""A key's full path: table keys (str) and array indices (int, from 0)."""

_BARE = re.compile(r"[A-Za-z0-9_-]+")
_SCALAR_END = re.compile(r"[,\]}#\r\n]")


def key_lines(text: str) -> dict[KeyPath, int]:
    """1-based line of each table header, key, array element and inline-table key of a TOML text.

    The first line wins when a path appears more than once (``[[a]]`` records ``("a",)`` at its first
    header and ``("a", n)`` at the n-th). See the module docstring for the paths.
    """
    scanner = _Scanner(text)
    with contextlib.suppress(_StopError):
        scanner.document()
    return scanner.lines


def find_line(lines: Mapping[KeyPath, int], path: KeyPath) -> int | None:
    """The line of ``path``, else of the first key or header under it, else of its nearest parent."""
    for end in range(len(path), 0, -1):
        prefix = path[:end]
        line = lines.get(prefix) or next((n for p, n in lines.items() if p[:end] == prefix), None)
        if line:
            return line
    return None


def dotted_path(path: Iterable[str | int]) -> str:
    """``("bodies", 1, "h")`` → ``"bodies[2].h"``: keys joined by dots, list items counted from 1."""
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part + 1}]"
        else:
            out += f".{part}" if out else part
    return out


def suggest(word: str, choices: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``choices``, or an empty string."""
    close = difflib.get_close_matches(word, list(choices), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def syntax_message(source: str, text: str, message: str) -> str:
    """``FILE:LINE: TOML syntax error: ...`` from tomllib's ``... (at line L, column C)`` message."""
    found = re.search(r"\s*\(at line (\d+), column (\d+)\)$", message)
    if found:
        return f"{source}:{found.group(1)}: TOML syntax error: {message[: found.start()]} (column {found.group(2)})"
    if message.endswith("(at end of document)"):
        line = text.count("\n") + (0 if text.endswith("\n") else 1)
        return f"{source}:{line}: TOML syntax error: {message.removesuffix(' (at end of document)')} at the end"
    return f"{source}: TOML syntax error: {message}"


class _StopError(Exception):
    """The scanner met something it does not understand (or the end of the text)."""


class _Scanner:
    """A position-only TOML reader: the values themselves come from tomllib."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.pos = 0
        self.lines: dict[KeyPath, int] = {}
        self.starts = [0] + [m.end() for m in re.finditer("\n", text)]
        self.arrays: dict[KeyPath, int] = {}  # array-of-tables path -> tables seen so far

    def line(self) -> int:
        return bisect.bisect_right(self.starts, self.pos)

    def record(self, path: KeyPath, line: int) -> None:
        self.lines.setdefault(path, line)

    def peek(self, n: int = 1) -> str:
        return self.text[self.pos:self.pos + n]

    def expect(self, token: str) -> None:
        if not self.text.startswith(token, self.pos):
            raise _StopError
        self.pos += len(token)

    def blank(self, newlines: bool) -> None:
        """Skip spaces and tabs (and comments and newlines when ``newlines``)."""
        while self.pos < len(self.text):
            c = self.text[self.pos]
            if c in " \t" or (newlines and c in "\r\n"):
                self.pos += 1
            elif newlines and c == "#":
                end = self.text.find("\n", self.pos)
                self.pos = len(self.text) if end < 0 else end
            else:
                return

    def document(self) -> None:
        section: KeyPath = ()
        while True:
            self.blank(newlines=True)
            if self.pos >= len(self.text):
                return
            line = self.line()
            if self.text.startswith("[[", self.pos):
                self.pos += 2
                key = self.key()
                self.blank(False)
                self.expect("]]")
                table = (*self.resolve(key[:-1]), key[-1])
                count = self.arrays.get(table, 0)
                self.arrays[table] = count + 1
                self.record(table, line)
                section = (*table, count)
                self.record(section, line)
            elif self.peek() == "[":
                self.pos += 1
                section = self.resolve(self.key())
                self.blank(False)
                self.expect("]")
                self.record(section, line)
            else:
                path = (*section, *self.key())
                self.blank(False)
                self.expect("=")
                self.record(path, line)
                self.value(path)

    def resolve(self, key: tuple[str, ...]) -> KeyPath:
        """A header's path with the current index after every array of tables it passes through."""
        path: KeyPath = ()
        for part in key:
            path = (*path, part)
            if path in self.arrays:
                path = (*path, self.arrays[path] - 1)
        return path

    def key(self) -> tuple[str, ...]:
        """A (dotted) key: bare, "basic" or 'literal' parts joined by dots."""
        parts = []
        while True:
            self.blank(False)
            c = self.peek()
            if c == '"':
                start = self.pos
                self.basic_string()
                parts.append(tomllib.loads(f"k = {self.text[start:self.pos]}")["k"])
            elif c == "'":
                end = self.text.find("'", self.pos + 1)
                if end < 0:
                    raise _StopError
                parts.append(self.text[self.pos + 1:end])
                self.pos = end + 1
            else:
                bare = _BARE.match(self.text, self.pos)
                if not bare:
                    raise _StopError
                parts.append(bare.group())
                self.pos = bare.end()
            self.blank(False)
            if self.peek() != ".":
                return tuple(parts)
            self.pos += 1

    def basic_string(self) -> None:
        """Skip a "basic string" (with backslash escapes)."""
        self.pos += 1
        while self.pos < len(self.text):
            c = self.text[self.pos]
            if c == "\\":
                self.pos += 2
            elif c == '"':
                self.pos += 1
                return
            else:
                self.pos += 1
        raise _StopError

    def multiline(self, quote: str) -> None:
        """Skip a multi-line string opened by three ``quote`` characters."""
        self.pos += 3
        while self.pos < len(self.text):
            if quote == '"' and self.text[self.pos] == "\\":
                self.pos += 2
            elif self.text.startswith(quote * 3, self.pos):
                self.pos += 3
                for _ in range(2):  # up to two quotes may stand just before the closing three
                    if self.peek() == quote:
                        self.pos += 1
                return
            else:
                self.pos += 1
        raise _StopError

    def value(self, path: KeyPath) -> None:
        self.blank(False)
        c = self.peek()
        if self.peek(3) in ('"""', "'''"):
            self.multiline(c)
        elif c == '"':
            self.basic_string()
        elif c == "'":
            end = self.text.find("'", self.pos + 1)
            if end < 0:
                raise _StopError
            self.pos = end + 1
        elif c == "[":
            self.array(path)
        elif c == "{":
            self.inline_table(path)
        else:
            scalar_end = _SCALAR_END.search(self.text, self.pos)
            self.pos = len(self.text) if scalar_end is None else scalar_end.start()

    def array(self, path: KeyPath) -> None:
        self.pos += 1
        index = 0
        while True:
            self.blank(newlines=True)
            if self.peek() == "]":
                self.pos += 1
                return
            self.record((*path, index), self.line())
            self.value((*path, index))
            index += 1
            self.blank(newlines=True)
            if self.peek() == ",":
                self.pos += 1
            elif self.peek() != "]":
                raise _StopError

    def inline_table(self, path: KeyPath) -> None:
        self.pos += 1
        while True:
            self.blank(newlines=True)
            if self.peek() == "}":
                self.pos += 1
                return
            line = self.line()
            key = (*path, *self.key())
            self.blank(False)
            self.expect("=")
            self.record(key, line)
            self.value(key)
            self.blank(newlines=True)
            if self.peek() == ",":
                self.pos += 1
            elif self.peek() != "}":
                raise _StopError
