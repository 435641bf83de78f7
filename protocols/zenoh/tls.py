"""The TLS identity of one of the rig's zenoh processes: a CA, its certificate and its private key.

Off loopback a zenoh link of the rig is TLS with mutual authentication (``docs/lab-network.md``): every process
presents its own certificate, signed by the lab's CA, and accepts only peers whose certificate that CA signed.
:func:`load_tls` checks the three files before zenoh sees them — zenoh reports a bad file only as a failed link,
long after the process started — and :class:`TlsFiles` holds their paths for ``protocols.zenoh.config``.

Each problem is one :class:`TlsError` line naming the option (``--tls-cert``, or ``FILE:LINE: network.tls.key``
from a rig configuration) and the file: missing, not PEM, a certificate that does not parse, expired or not yet
valid, not signed by the CA, a key that is not the certificate's, a key readable by group or others.

zenoh says only "Unable to connect … Timeout!" (or nothing: a peer keeps trying) when a TLS link fails. When a
process gets no answer over ``tls/``, :func:`why_no_link` makes one TLS handshake of its own with the same files
and says which side refused which certificate.
"""

from __future__ import annotations

import datetime as dt
import socket
import ssl
import stat
from pathlib import Path
from typing import NamedTuple

from cryptography import x509
from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import ec, ed25519, rsa
from cryptography.hazmat.primitives.asymmetric.types import CertificatePublicKeyTypes

from protocols.private_file import PrivateFileError, SharedPrivateFileError, read_private_file

MAX_PEM_BYTES = 1 << 20
"""Largest certificate or key file read [bytes]."""


class TlsError(ValueError):
    """A TLS file that cannot be used (one line: the option, the file, what is wrong)."""


class TlsFiles(NamedTuple):
    """Paths of a process's TLS identity: the lab's ``ca`` certificate, this process's ``certificate`` (signed by
    the CA; a server's names the addresses it listens on) and its private ``key`` (PEM, PKCS#8 or traditional)."""

    ca: Path
    certificate: Path
    key: Path


class TlsOptions(NamedTuple):
    """Where each of the three files came from, for messages: ``--tls-ca`` or ``rig.toml:12: network.tls.ca``."""

    ca: str = "--tls-ca"
    certificate: str = "--tls-cert"
    key: str = "--tls-key"


CLI_OPTIONS = TlsOptions()
"""The command line's names of the three files."""


def load_tls(ca: Path | str | None, certificate: Path | str | None, key: Path | str | None, *,
             names: TlsOptions = CLI_OPTIONS, now: dt.datetime | None = None) -> TlsFiles | None:
    """The three files checked (module docstring), or None when none is given; :class:`TlsError` when only some
    are given or one cannot be used. ``now`` (UTC) is when validity is judged (default: now)."""
    given = {"ca": ca, "certificate": certificate, "key": key}
    if all(value is None for value in given.values()):
        return None
    if ca is None or certificate is None or key is None:
        missing = [getattr(names, field) for field, value in given.items() if value is None]
        have = ", ".join(getattr(names, field) for field, value in given.items() if value is not None)
        raise TlsError(f"{have} given without {' and '.join(missing)}: a TLS identity is the CA, the certificate "
                       "and its key together")
    files = TlsFiles(Path(ca).expanduser(), Path(certificate).expanduser(), Path(key).expanduser())
    when = now or dt.datetime.now(dt.UTC)
    authority = _certificate(files.ca, names.ca, when)
    if not _is_ca(authority):
        raise TlsError(f"{names.ca} {files.ca}: not a CA certificate (no basicConstraints CA:TRUE)")
    own = _certificate(files.certificate, names.certificate, when)
    try:
        own.verify_directly_issued_by(authority)
    except (ValueError, TypeError, InvalidSignature):
        raise TlsError(f"{names.certificate} {files.certificate}: not signed by the CA {files.ca} "
                       f"({authority.subject.rfc4514_string()})") from None
    private = _private_key(files.key, names.key)
    if _public_bytes(private.public_key()) != _public_bytes(own.public_key()):
        raise TlsError(f"{names.key} {files.key}: not the private key of {names.certificate} {files.certificate}")
    return files


def _read(path: Path, option: str) -> bytes:
    try:
        info = path.stat()
    except FileNotFoundError:
        raise TlsError(f"{option} {path}: no such file") from None
    except OSError as exc:
        raise TlsError(f"{option} {path}: {exc.strerror}") from None
    if not stat.S_ISREG(info.st_mode):
        raise TlsError(f"{option} {path}: not a regular file")
    if info.st_size > MAX_PEM_BYTES:
        raise TlsError(f"{option} {path}: {info.st_size} bytes, more than a PEM file's {MAX_PEM_BYTES}")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise TlsError(f"{option} {path}: {exc.strerror}") from None
    return _pem(data, path, option)


def _read_key(path: Path, option: str) -> bytes:
    """The private key file's bytes, refused as :func:`_read` refuses a file and when others may read it."""
    try:
        data = read_private_file(path, f"{option} {path}", "the TLS key", MAX_PEM_BYTES)
    except SharedPrivateFileError as exc:
        raise TlsError(f"{option} {path}: readable by others (mode {exc.mode:04o}): chmod 600 {path}") from None
    except PrivateFileError as exc:
        if isinstance(exc.__cause__, FileNotFoundError):
            raise TlsError(f"{option} {path}: no such file") from None
        raise TlsError(str(exc)) from None
    if len(data) > MAX_PEM_BYTES:
        raise TlsError(f"{option} {path}: {path.stat().st_size} bytes, more than a PEM file's {MAX_PEM_BYTES}")
    return _pem(data, path, option)


def _pem(data: bytes, path: Path, option: str) -> bytes:
    """``data`` read from ``path`` if it is a PEM file."""
    if b"-----BEGIN " not in data:
        raise TlsError(f"{option} {path}: not a PEM file (no -----BEGIN line)")
    return data


def _certificate(path: Path, option: str, now: dt.datetime) -> x509.Certificate:
    data = _read(path, option)
    try:
        certificates = x509.load_pem_x509_certificates(data)
    except ValueError as exc:
        raise TlsError(f"{option} {path}: not a PEM certificate ({exc})") from None
    certificate = certificates[0]
    if now < certificate.not_valid_before_utc:
        raise TlsError(f"{option} {path}: not valid before {certificate.not_valid_before_utc:%Y-%m-%d %H:%M} UTC")
    if now > certificate.not_valid_after_utc:
        raise TlsError(f"{option} {path}: expired on {certificate.not_valid_after_utc:%Y-%m-%d %H:%M} UTC")
    return certificate


def _is_ca(certificate: x509.Certificate) -> bool:
    try:
        return bool(certificate.extensions.get_extension_for_class(x509.BasicConstraints).value.ca)
    except x509.ExtensionNotFound:
        return False


def _private_key(path: Path, option: str) -> ec.EllipticCurvePrivateKey | rsa.RSAPrivateKey | ed25519.Ed25519PrivateKey:
    data = _read_key(path, option)
    try:
        key = serialization.load_pem_private_key(data, password=None)
    except (ValueError, TypeError) as exc:
        raise TlsError(f"{option} {path}: not an unencrypted PEM private key ({exc})") from None
    if not isinstance(key, ec.EllipticCurvePrivateKey | rsa.RSAPrivateKey | ed25519.Ed25519PrivateKey):
        raise TlsError(f"{option} {path}: a {type(key).__name__}; zenoh takes EC, RSA or Ed25519 keys")
    return key


def _public_bytes(key: CertificatePublicKeyTypes) -> bytes:
    return key.public_bytes(serialization.Encoding.DER, serialization.PublicFormat.SubjectPublicKeyInfo)


def why_no_link(endpoint: str, files: TlsFiles, timeout: float = 2.0) -> str:
    """Why a zenoh TLS link to ``endpoint`` (``tls/ADDRESS:PORT``) is not made, from a TLS handshake with ``files``
    (the connecting process's identity): nothing listens, the listener's certificate is not signed by our CA or does
    not name the address, the listener refused our certificate — or the handshake succeeds (the cause is elsewhere).
    One sentence, for an error message."""
    address, _, port = endpoint.removeprefix("tls/").rpartition(":")
    host = address.strip("[]")
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    context.minimum_version = ssl.TLSVersion.TLSv1_2
    try:
        context.load_verify_locations(cafile=files.ca)
        context.load_cert_chain(files.certificate, files.key)
    except (OSError, ssl.SSLError) as exc:
        return f"this process's TLS files cannot be loaded ({exc})"
    try:
        raw = socket.create_connection((host, int(port)), timeout=timeout)
    except OSError as exc:
        return f"nothing answers at {host}:{port} ({exc.strerror or exc})"
    with raw:
        try:
            with context.wrap_socket(raw, server_hostname=host) as tls:
                tls.settimeout(min(timeout, 0.5))
                try:
                    tls.recv(1)  # TLS 1.3: a listener that refuses our certificate says so after the handshake
                except TimeoutError:
                    return (f"a TLS handshake with {host}:{port} succeeds with these certificates (the listener "
                            "accepts ours): the table or service there does not answer")
                except ssl.SSLError as exc:
                    return (f"the listener at {host}:{port} refused this process's certificate {files.certificate} "
                            f"(not signed by the CA it trusts? {exc.reason or exc})")
        except ssl.SSLCertVerificationError as exc:
            if exc.verify_code == 62 or "mismatch" in str(exc.verify_message):  # X509_V_ERR_HOSTNAME/IP_MISMATCH
                return (f"the certificate of the listener at {host}:{port} does not name {host} (make it with "
                        f"rig certs make DIR --name NAME --ip {host})")
            return (f"the certificate of the listener at {host}:{port} is not trusted by the CA {files.ca} "
                    f"({exc.verify_message})")
        except ssl.SSLError as exc:
            return (f"the listener at {host}:{port} refused this process's certificate {files.certificate} "
                    f"(not signed by the CA it trusts? {exc.reason or exc})")
        except OSError as exc:
            return f"the TLS handshake with {host}:{port} failed ({exc})"
    return f"the listener at {host}:{port} closed the link"
