"""The lab's certificates (``rig certs make``): one CA, and a certificate and key per process.

A directory holds the lab's CA (``ca.pem``, its key ``ca.key``) and, per process, ``NAME.pem`` and ``NAME.key``
(an EC P-256 key, PKCS#8 PEM). The CA is made on the first call and reused by the next ones, so every identity made
in one directory trusts the others (``docs/lab-network.md``). A process's certificate carries its name as the common
name and, as subject alternative names, the IP addresses and DNS names it is reached at: a TLS client checks that
the listener it connects to is named by the address it dialled (zenoh's ``verify_name_on_connect``; a browser for
the console), so the table controller's certificate names the address it listens on. Key files are created with
mode 0600 and never overwritten. The certificates are valid from one hour before ``now`` (clocks a little apart)
for ``days``.
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import os
import re
from pathlib import Path
from typing import NamedTuple

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

CA_NAME = "ca"
"""File stem of the lab's CA in a certificates directory."""

MAX_DAYS = 3650
"""Longest validity of a certificate [days]."""

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,62}")


class CertError(ValueError):
    """A certificate that cannot be made (one line: which file or option, what is wrong)."""


class Identity(NamedTuple):
    """The files of one process's TLS identity (``--tls-ca``, ``--tls-cert``, ``--tls-key``)."""

    ca: Path
    certificate: Path
    key: Path
    made_ca: bool
    """The CA was made by this call (not found in the directory)."""


def make_identity(directory: Path, name: str, *, addresses: tuple[str, ...] = (), dns: tuple[str, ...] = (),
                  days: int = 825, now: dt.datetime | None = None) -> Identity:
    """Make ``directory/NAME.pem`` and ``NAME.key`` signed by the directory's CA (made first when absent; module
    docstring). ``addresses`` IP addresses and ``dns`` names the process is reached at; ``days`` of validity from
    ``now`` (UTC, default now). :class:`CertError` for a bad name, address or duration, or a file that exists."""
    if not _NAME.fullmatch(name) or name == CA_NAME:
        raise CertError(f"--name {name!r}: expected 1-63 letters, digits, '.', '_' or '-' (not {CA_NAME!r})")
    ips = []
    for text in addresses:
        try:
            ips.append(ipaddress.ip_address(text))
        except ValueError:
            raise CertError(f"--ip {text!r}: not an IP address") from None
    for text in dns:
        if not re.fullmatch(r"[A-Za-z0-9]([A-Za-z0-9.-]{0,251}[A-Za-z0-9])?", text):
            raise CertError(f"--dns {text!r}: not a DNS name")
    if not 1 <= days <= MAX_DAYS:
        raise CertError(f"--days {days}: expected 1..{MAX_DAYS}")
    when = now or dt.datetime.now(dt.UTC)
    directory.mkdir(parents=True, exist_ok=True)
    certificate, key = directory / f"{name}.pem", directory / f"{name}.key"
    for path in (certificate, key):
        if path.exists():
            raise CertError(f"{path}: exists (a certificate is never overwritten: remove it or choose another --name)")
    ca_certificate, ca_key, made_ca = _ca(directory, when)
    own_key = ec.generate_private_key(ec.SECP256R1())
    sans: list[x509.GeneralName] = [x509.IPAddress(ip) for ip in ips] + [x509.DNSName(d) for d in dns]
    builder = (_builder(name, own_key, when, days).issuer_name(ca_certificate.subject)
               .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
               .add_extension(x509.KeyUsage(digital_signature=True, key_encipherment=False, content_commitment=False,
                                            data_encipherment=False, key_agreement=True, key_cert_sign=False,
                                            crl_sign=False, encipher_only=False, decipher_only=False), critical=True)
               .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH,
                                                     ExtendedKeyUsageOID.CLIENT_AUTH]), critical=False)
               .add_extension(x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()),
                              critical=False))
    if sans:
        builder = builder.add_extension(x509.SubjectAlternativeName(sans), critical=False)
    _write_key(key, own_key)
    certificate.write_bytes(builder.sign(ca_key, hashes.SHA256()).public_bytes(serialization.Encoding.PEM))
    return Identity(directory / f"{CA_NAME}.pem", certificate, key, made_ca)


def fingerprint(path: Path) -> str:
    """SHA-256 fingerprint of the PEM certificate ``path`` (``AB:CD:…``, what a browser shows)."""
    certificate = x509.load_pem_x509_certificate(path.read_bytes())
    return ":".join(f"{byte:02X}" for byte in certificate.fingerprint(hashes.SHA256()))


def _ca(directory: Path, now: dt.datetime) -> tuple[x509.Certificate, ec.EllipticCurvePrivateKey, bool]:
    """The directory's CA, made (valid :data:`MAX_DAYS`) when neither of its files exists."""
    certificate, key = directory / f"{CA_NAME}.pem", directory / f"{CA_NAME}.key"
    if certificate.exists() != key.exists():
        present, absent = (certificate, key) if certificate.exists() else (key, certificate)
        raise CertError(f"{present} exists without {absent}: the CA is both files")
    if certificate.exists():
        try:
            ca_certificate = x509.load_pem_x509_certificate(certificate.read_bytes())
        except ValueError as exc:
            raise CertError(f"{certificate}: not a PEM certificate ({exc})") from None
        try:
            ca_key = serialization.load_pem_private_key(key.read_bytes(), password=None)
        except (ValueError, TypeError) as exc:
            raise CertError(f"{key}: not an unencrypted PEM private key ({exc})") from None
        if not isinstance(ca_key, ec.EllipticCurvePrivateKey):
            raise CertError(f"{key}: not an EC key (made by rig certs make?)")
        return ca_certificate, ca_key, False
    ca_key = ec.generate_private_key(ec.SECP256R1())
    builder = (_builder(f"shaketable-rig lab CA ({directory.resolve().name})", ca_key, now, MAX_DAYS)
               .issuer_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME,
                                                          f"shaketable-rig lab CA ({directory.resolve().name})")]))
               .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
               .add_extension(x509.KeyUsage(digital_signature=False, key_encipherment=False, content_commitment=False,
                                            data_encipherment=False, key_agreement=False, key_cert_sign=True,
                                            crl_sign=True, encipher_only=False, decipher_only=False), critical=True))
    ca_certificate = builder.sign(ca_key, hashes.SHA256())
    _write_key(key, ca_key)
    certificate.write_bytes(ca_certificate.public_bytes(serialization.Encoding.PEM))
    return ca_certificate, ca_key, True


def _builder(common_name: str, key: ec.EllipticCurvePrivateKey, now: dt.datetime, days: int) -> x509.CertificateBuilder:
    return (x509.CertificateBuilder()
            .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common_name)]))
            .public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - dt.timedelta(hours=1)).not_valid_after(now + dt.timedelta(days=days))
            .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False))


def _write_key(path: Path, key: ec.EllipticCurvePrivateKey) -> None:
    """``key`` as PKCS#8 PEM in a new file of mode 0600 (never overwriting one)."""
    data = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "wb") as out:
        out.write(data)
