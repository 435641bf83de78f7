"""The URL registry: backends chosen by a URL scheme.

Like python-can's ``Bus``: :func:`open_table` takes ``scheme://…`` and returns a :class:`TableController` of
the backend registered for that scheme (``mavlink://HOST:PORT`` → :mod:`drivers.mavlink`; other transports
register with :func:`register_scheme`). :mod:`drivers.controller` re-exports every name here.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any
from urllib.parse import urlsplit

from drivers.interface import TableController

Factory = Callable[..., TableController]

_registry: dict[str, Factory] = {}

_BUILTIN = {"mavlink": "drivers.mavlink", "canopen": "drivers.canopen", "zenoh": "drivers.zenoh"}
"""Schemes whose backend module registers itself on import (imported on first use)."""


def register_scheme(scheme: str, factory: Factory) -> None:
    """Make ``open_table("scheme://…", **options)`` call ``factory(url, **options)``."""
    _registry[scheme.lower()] = factory


def open_table(url: str, **options: Any) -> TableController:
    """A controller for ``url`` (``mavlink://127.0.0.1:14600``, …), not yet connected: call
    :meth:`~TableController.connect` or use it in a ``with`` block. ``options`` go to the backend."""
    scheme = urlsplit(url).scheme.lower()
    if not scheme:
        raise ValueError(f"table URL {url!r} has no scheme; expected e.g. mavlink://127.0.0.1:14600")
    if scheme not in _registry and scheme in _BUILTIN:
        importlib.import_module(_BUILTIN[scheme])
    if scheme not in _registry:
        known = sorted(set(_registry) | set(_BUILTIN))
        raise ValueError(f"table URL {url!r}: unknown scheme {scheme!r}; known: {', '.join(known)}")
    return _registry[scheme](url, **options)


def host_port(url: str, default_host: str = "127.0.0.1") -> tuple[str, int]:
    """``(host, port)`` of ``scheme://HOST:PORT`` (:class:`ValueError` when the port is missing or bad)."""
    parts = urlsplit(url)
    try:
        port = parts.port
    except ValueError:
        port = None
    if port is None or parts.path not in ("", "/"):
        raise ValueError(f"table URL {url!r}: expected {parts.scheme or 'scheme'}://HOST:PORT")
    return parts.hostname or default_host, port
