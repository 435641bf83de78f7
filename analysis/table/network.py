"""The ``[network]`` table of the rig configuration: this machine's TLS identity on the lab network
(``docs/lab-network.md``), used by ``rig run``, ``rig serve`` and ``rig emulate`` for a zenoh link when
``--tls-ca``, ``--tls-cert`` and ``--tls-key`` are not given, and the console's HTTPS and tokens
(``[network.console]``, ``docs/console.md``), used by ``rig serve --http``, ``rig console`` and ``rig run --console``
for the options of theirs not given.

```toml
[network]
ca = "certs/ca.pem"       # the lab's CA certificate (relative to this file)
cert = "certs/rig.pem"    # this process's certificate, signed by the CA (rig certs make)
key = "certs/rig.key"     # its private key (mode 0600)

[network.console]                 # each key optional
https_cert = "web/console.pem"    # its HTTPS certificate and key (together), or
https_key = "web/console.key"
# https_dir = "web"               # a certificate made there on first use
names = ["rig.lab"]               # names browsers reach it at (--http-name)
tokens = "tokens.toml"            # operators and viewers (--tokens)
```

The three TLS files go together (or none). Here each path is checked to be a string naming an existing regular file
(``https_dir`` may not exist yet: the console makes it); the certificates themselves (PEM, signed by the CA, valid
now, the key the certificate's, the key's mode) are checked where they are used (``protocols.zenoh.tls.load_tls``),
whose errors name the same ``FILE:LINE: network.KEY`` (:attr:`NetworkSettings.where`). Errors are
``FILE:LINE: network.KEY: problem``.

The identity is the machine's, not the table's: a session file does not keep it (``configuration_dict`` does not
write it, and two configurations that differ only in it are equal), so a resumed session is given it again.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from analysis.table.toml_check import TomlChecker, shown

KEYS = ("ca", "cert", "key")
"""The keys of ``[network]``'s TLS identity, in the order of its three files."""

CONSOLE_KEYS = ("https_cert", "https_key", "https_dir", "names", "tokens")
"""The keys of ``[network.console]``."""

_WHAT = {"ca": "the lab's CA certificate", "cert": "this process's certificate", "key": "its private key",
         "https_cert": "the console's HTTPS certificate", "https_key": "its private key",
         "tokens": "the tokens file of operators and viewers"}


@dataclass(frozen=True)
class ConsoleSettings:
    """The console's HTTPS certificate (``https_cert`` and ``https_key``, or ``https_dir`` where one is made on
    first use), the ``names`` browsers reach it at and its ``tokens`` file (``rig.console.WebAccess``); paths
    resolved against the configuration's folder, None (``()``) when not given."""

    names: tuple[str, ...] = ()
    tokens: Path | None = None
    https_cert: Path | None = None
    https_key: Path | None = None
    https_dir: Path | None = None


@dataclass(frozen=True)
class NetworkSettings:
    """This machine's TLS identity (``ca``, ``cert``, ``key``: absolute or as given, resolved against the
    configuration's folder), all None when the configuration has no ``[network]``. ``where`` names each key as the
    configuration wrote it (``rig.toml:3: network.ca``) for the messages of the certificate checks."""

    ca: Path | None = None
    cert: Path | None = None
    key: Path | None = None
    where: tuple[str, str, str] = field(default=("network.ca", "network.cert", "network.key"), compare=False)
    console: ConsoleSettings = ConsoleSettings()

    @property
    def given(self) -> bool:
        """Whether the configuration names a TLS identity."""
        return self.ca is not None


def read_network(checker: TomlChecker, value: Any) -> NetworkSettings:
    """The ``[network]`` table read by ``checker`` (its source file is the folder relative paths start from);
    ``NetworkSettings()`` when ``value`` is None (no such table)."""
    if value is None:
        return NetworkSettings()
    path = ("network",)
    table: Mapping[str, Any] = checker.table(value, path, (*KEYS, "console"))
    console = _read_console(checker, table.get("console"))
    present = [key for key in KEYS if key in table]
    if not present:
        return NetworkSettings(console=console)
    missing = [key for key in KEYS if key not in table]
    if missing:
        given = ", ".join(f"network.{key}" for key in present)
        raise checker.error((*path, present[0]), f"{given} given without "
                                                 f"{' and '.join(f'network.{key}' for key in missing)}: a TLS "
                                                 "identity is the CA, the certificate and its key together")
    files = [_file(checker, table[key], (*path, key)) for key in KEYS]
    where = [_where(checker, (*path, key)) for key in KEYS]
    return NetworkSettings(files[0], files[1], files[2], (where[0], where[1], where[2]), console)


def _read_console(checker: TomlChecker, value: Any) -> ConsoleSettings:
    if value is None:
        return ConsoleSettings()
    path = ("network", "console")
    table: Mapping[str, Any] = checker.table(value, path, CONSOLE_KEYS)
    pair = [key for key in ("https_cert", "https_key") if key in table]
    if len(pair) == 1:
        other = "https_key" if pair[0] == "https_cert" else "https_cert"
        raise checker.error((*path, pair[0]), f"network.console.{pair[0]} given without network.console.{other}: "
                                              "the console's certificate and its key go together")
    if pair and "https_dir" in table:
        raise checker.error((*path, "https_dir"), "network.console.https_dir with https_cert and https_key: give "
                                                  "the certificate, or the folder one is made in, not both")
    names = table.get("names", [])
    if not isinstance(names, list) or not all(isinstance(n, str) and n.strip() and not any(c.isspace() for c in n)
                                              for n in names):
        raise checker.error((*path, "names"), f"expected a list of DNS names or addresses (strings without "
                                              f"spaces), got {shown(names)}")
    files = {key: _file(checker, table[key], (*path, key)) for key in ("https_cert", "https_key", "tokens")
             if key in table}
    directory = None
    if "https_dir" in table:
        directory = _path(checker, table["https_dir"], (*path, "https_dir"), "the folder of the console's "
                                                                               "certificate")
        if directory.exists() and not directory.is_dir():
            raise checker.error((*path, "https_dir"), f"{str(directory)!r}: not a folder")
    return ConsoleSettings(tuple(names), files.get("tokens"), files.get("https_cert"), files.get("https_key"),
                           directory)


def _path(checker: TomlChecker, raw: Any, at: tuple[str, ...], what: str) -> Path:
    """``raw`` as a path relative to the configuration's folder; refused unless a non-empty string."""
    if not isinstance(raw, str) or not raw.strip():
        raise checker.error(at, f"expected the path of {what} (a string), got {shown(raw)}")
    file = Path(raw).expanduser()
    return file if file.is_absolute() else Path(checker.source).parent / file


def _file(checker: TomlChecker, raw: Any, at: tuple[str, ...]) -> Path:
    """``raw`` as the path of an existing regular file (:func:`_path`)."""
    what = _WHAT[at[-1]]
    file = _path(checker, raw, at, what)
    if not file.is_file():
        problem = "not a regular file" if file.exists() else "no such file"
        raise checker.error(at, f"{what} {str(file)!r}: {problem}")
    return file


def _where(checker: TomlChecker, at: tuple[str, ...]) -> str:
    """``FILE:LINE: network.KEY`` (without the line when it is not known)."""
    line = checker.line(at)
    dotted = ".".join(at)
    return f"{checker.source}:{line}: {dotted}" if line else f"{checker.source}: {dotted}"
