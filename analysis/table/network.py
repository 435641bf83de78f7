"""The ``[network]`` table of the rig configuration: this machine's TLS identity on the lab network
(``docs/lab-network.md``), used by ``rig run`` and ``rig emulate`` for a zenoh link when ``--tls-ca``, ``--tls-cert``
and ``--tls-key`` are not given.

```toml
[network]
ca = "certs/ca.pem"       # the lab's CA certificate (relative to this file)
cert = "certs/rig.pem"    # this process's certificate, signed by the CA (rig certs make)
key = "certs/rig.key"     # its private key (mode 0600)
```

The three go together (or none: no ``[network]``). Here each is checked to be a string naming an existing regular
file; the certificates themselves (PEM, signed by the CA, valid now, the key the certificate's, the key's mode) are
checked where they are used (``protocols.zenoh.tls.load_tls``), whose errors name the same ``FILE:LINE: network.KEY``
(:attr:`NetworkSettings.where`). Errors are ``FILE:LINE: network.KEY: problem``.

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
"""The keys of ``[network]``, in the order of a TLS identity's three files."""

_WHAT = {"ca": "the lab's CA certificate", "cert": "this process's certificate", "key": "its private key"}


@dataclass(frozen=True)
class NetworkSettings:
    """This machine's TLS identity (``ca``, ``cert``, ``key``: absolute or as given, resolved against the
    configuration's folder), all None when the configuration has no ``[network]``. ``where`` names each key as the
    configuration wrote it (``rig.toml:3: network.ca``) for the messages of the certificate checks."""

    ca: Path | None = None
    cert: Path | None = None
    key: Path | None = None
    where: tuple[str, str, str] = field(default=("network.ca", "network.cert", "network.key"), compare=False)

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
    table: Mapping[str, Any] = checker.table(value, path, KEYS)
    missing = [key for key in KEYS if key not in table]
    if missing:
        present = [key for key in KEYS if key in table]
        at = (*path, present[0]) if present else path
        given = ", ".join(f"network.{key}" for key in present) or "[network]"
        raise checker.error(at, f"{given} given without {' and '.join(f'network.{key}' for key in missing)}: a TLS "
                                "identity is the CA, the certificate and its key together")
    folder = Path(checker.source).parent
    files: dict[str, Path] = {}
    where: list[str] = []
    for key in KEYS:
        raw = table[key]
        if not isinstance(raw, str) or not raw.strip():
            raise checker.error((*path, key), f"expected the path of {_WHAT[key]} (a string), got {shown(raw)}")
        file = Path(raw).expanduser()
        file = file if file.is_absolute() else folder / file
        if not file.is_file():
            problem = "not a regular file" if file.exists() else "no such file"
            raise checker.error((*path, key), f"{_WHAT[key]} {str(file)!r}: {problem}")
        files[key] = file
        line = checker.line((*path, key))
        where.append(f"{checker.source}:{line}: network.{key}" if line else f"{checker.source}: network.{key}")
    return NetworkSettings(files["ca"], files["cert"], files["key"], (where[0], where[1], where[2]))
