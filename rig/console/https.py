"""The console's HTTPS certificate: given (``--https-cert FILE --https-key FILE``, e.g. made by ``rig certs make
--name console --ip ADDRESS``) or made on first use in a directory (``--https-dir DIR``: ``DIR/console.pem`` and
``console.key``, signed by the directory's lab CA ``DIR/ca.pem``, made by :func:`rig.certs.make_identity` and reused
by the next starts). The certificate's SHA-256 fingerprint is printed at every start so that the operator can compare
it with what the browser shows (or install ``DIR/ca.pem`` in the browsers once).

A console that listens off loopback serves HTTPS only: the operator's token and the page would otherwise cross the
lab network in clear.
"""

from __future__ import annotations

import ipaddress
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

from cryptography import x509
from cryptography.hazmat.primitives import serialization

from rig.certs import CertError, fingerprint, make_identity

CONSOLE_NAME = "console"
"""File stem of the certificate made in ``--https-dir``."""


class HttpsError(ValueError):
    """The HTTPS options are unusable (one line: the option and file, what is wrong)."""


class HttpsFiles(NamedTuple):
    """The certificate (PEM, its chain) and private key (PEM, unencrypted) the console serves HTTPS with."""

    certificate: Path
    key: Path


def is_loopback(host: str) -> bool:
    """``host`` (an address or ``localhost``) is this machine's loopback."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def https_files(host: str, names: tuple[str, ...], *, certificate: Path | None, key: Path | None,
                directory: Path | None, say: Callable[[str], None]) -> HttpsFiles | None:
    """The certificate to serve at ``host`` (module docstring), None for plain HTTP (loopback only); ``names`` the
    DNS names the console is reached at (put in a certificate made here). Says the fingerprint. :class:`HttpsError`
    for a missing half, a file that does not parse, or plain HTTP off loopback."""
    if (certificate is None) != (key is None):
        given, missing = ("--https-cert", "--https-key") if certificate is not None else ("--https-key", "--https-cert")
        raise HttpsError(f"{given} without {missing}: the console needs both the certificate and its key")
    if certificate is not None and directory is not None:
        raise HttpsError("--https-dir with --https-cert: give one of them")
    if directory is not None:
        certificate, key = directory / f"{CONSOLE_NAME}.pem", directory / f"{CONSOLE_NAME}.key"
        if not certificate.exists() and not key.exists():
            addresses = (host,) if not is_loopback(host) and _is_address(host) else ()
            try:
                make_identity(directory, CONSOLE_NAME, addresses=(*addresses, "127.0.0.1"),
                              dns=(*(n for n in names if not _is_address(n)), "localhost"))
            except CertError as exc:
                raise HttpsError(f"--https-dir {directory}: {exc}") from None
            say(f"made the console's certificate {certificate} (CA {directory / 'ca.pem'})")
    if certificate is None or key is None:
        if not is_loopback(host):
            raise HttpsError(f"--http {host}: not on loopback: serve HTTPS (--https-dir DIR, or --https-cert and "
                             f"--https-key) so that the page and the tokens do not cross the network in clear")
        return None
    _check(certificate, key)
    say(f"HTTPS certificate {certificate}, SHA-256 fingerprint {fingerprint(certificate)}: compare it with the "
        f"browser's")
    return HttpsFiles(certificate, key)


def _is_address(text: str) -> bool:
    try:
        ipaddress.ip_address(text)
    except ValueError:
        return False
    return True


def _check(certificate: Path, key: Path) -> None:
    """Both files parse and the key is the certificate's; else :class:`HttpsError` naming the file."""
    try:
        cert = x509.load_pem_x509_certificate(certificate.read_bytes())
    except OSError as exc:
        raise HttpsError(f"--https-cert {certificate}: {exc.strerror or exc}") from None
    except ValueError:
        raise HttpsError(f"--https-cert {certificate}: not a PEM certificate") from None
    try:
        private = serialization.load_pem_private_key(key.read_bytes(), password=None)
    except OSError as exc:
        raise HttpsError(f"--https-key {key}: {exc.strerror or exc}") from None
    except (ValueError, TypeError):
        raise HttpsError(f"--https-key {key}: not an unencrypted PEM private key") from None
    public = serialization.PublicFormat.SubjectPublicKeyInfo
    if (private.public_key().public_bytes(serialization.Encoding.DER, public)
            != cert.public_key().public_bytes(serialization.Encoding.DER, public)):
        raise HttpsError(f"--https-key {key}: not the key of the certificate {certificate}")
