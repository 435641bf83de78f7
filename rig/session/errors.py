"""Errors of the session log."""

from __future__ import annotations


class SessionError(Exception):
    """A session file cannot be written or read as asked; the message names the file and what was expected."""


class SessionExistsError(SessionError, FileExistsError):
    """The session file to create already exists (a session file is never overwritten)."""
