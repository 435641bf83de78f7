"""The lab network in process (docs/lab-network.md): the zenoh session configuration with a TLS identity, the checks
of the TLS files, the certificates ``rig certs make`` writes, the command line's refusals, and the rig
configuration's ``[network]`` (read, refused with FILE:LINE, used by ``rig run`` and the emulator). No socket is
opened (the links themselves: tests/transports/test_lab_network_netns.py)."""

from __future__ import annotations

import datetime as dt
import json
import stat
from pathlib import Path

import pytest
from cryptography import x509
from typer.testing import CliRunner

from analysis.table.limits import TableModelError
from analysis.table.model import TableModel
from protocols.zenoh import EndpointError, LinkSecurity, session_config
from protocols.zenoh.tls import TlsError, TlsFiles, TlsOptions, load_tls
from rig.certs import CertError, make_identity
from rig.cli import app
from rig.cli.network import configured_security
from sim_table.process import parse_args
from tests.helpers.sequences import TINY


@pytest.fixture
def lab(tmp_path: Path) -> Path:
    """A certificates directory with the lab CA, the table's identity (10.231.0.2) and the rig's."""
    make_identity(tmp_path / "certs", "table", addresses=("10.231.0.2",))
    make_identity(tmp_path / "certs", "rig")
    return tmp_path / "certs"


def _files(directory: Path, name: str, ca: Path | None = None) -> TlsFiles:
    return TlsFiles(ca or directory / "ca.pem", directory / f"{name}.pem", directory / f"{name}.key")


# ----- session configuration ----------------------------------------------------------------------------------


def test_a_tls_identity_makes_every_link_mutual_tls(lab: Path) -> None:
    files = load_tls(*_files(lab, "table"))
    config = session_config(listen=["tls/10.231.0.2:7447"], security=LinkSecurity(files))
    tls = json.loads(config.get_json("transport/link/tls"))
    assert tls["root_ca_certificate"] == str((lab / "ca.pem").resolve())
    assert tls["listen_certificate"] == tls["connect_certificate"] == str((lab / "table.pem").resolve())
    assert tls["listen_private_key"] == tls["connect_private_key"] == str((lab / "table.key").resolve())
    assert tls["enable_mtls"] is True and tls["verify_name_on_connect"] is True
    assert tls["close_link_on_expiration"] is True
    assert json.loads(config.get_json("transport/link/protocols")) == ["tls"]  # no plain link beside it
    assert json.loads(config.get_json("listen/endpoints")) == ["tls/10.231.0.2:7447"]


def test_plain_text_off_loopback_only_when_asked(lab: Path) -> None:
    with pytest.raises(EndpointError, match=r"'tcp/10\.231\.0\.2:7447' is off loopback and not encrypted"):
        session_config(connect=["tcp/10.231.0.2:7447"])
    insecure = session_config(connect=["tcp/10.231.0.2:7447"], security=LinkSecurity(insecure=True))
    assert json.loads(insecure.get_json("connect/endpoints")) == ["tcp/10.231.0.2:7447"]
    assert json.loads(insecure.get_json("transport/link/tls"))["root_ca_certificate"] is None
    with pytest.raises(EndpointError, match=r"is TLS but no TLS identity is given"):
        session_config(connect=["tls/10.231.0.2:7447"])
    with pytest.raises(EndpointError, match=r"'tcp/127\.0\.0\.1:7447' is plain text but a TLS identity is given: "
                                            r"use tls/127\.0\.0\.1:7447"):
        session_config(connect=["tcp/127.0.0.1:7447"], security=LinkSecurity(load_tls(*_files(lab, "rig"))))
    assert LinkSecurity(load_tls(*_files(lab, "rig"))).endpoint("::1", 7447) == "tls/[::1]:7447"


# ----- the TLS files ------------------------------------------------------------------------------------------


def test_tls_files_are_all_three_or_none(lab: Path) -> None:
    assert load_tls(None, None, None) is None
    with pytest.raises(TlsError, match=r"^--tls-ca, --tls-cert given without --tls-key: a TLS identity is the CA"):
        load_tls(lab / "ca.pem", lab / "rig.pem", None)


def test_each_bad_tls_file_is_named_with_what_is_wrong(lab: Path, tmp_path: Path) -> None:
    other = tmp_path / "other"
    make_identity(other, "rig")
    garbage = tmp_path / "garbage.pem"
    garbage.write_text("-----BEGIN CERTIFICATE-----\nnot base64 at all\n-----END CERTIFICATE-----\n")
    text = tmp_path / "text.pem"
    text.write_text("hello\n")
    cases = [
        ((lab / "nope.pem", lab / "rig.pem", lab / "rig.key"), r"^--tls-ca \S+nope\.pem: no such file$"),
        ((lab / "ca.pem", text, lab / "rig.key"), r"^--tls-cert \S+text\.pem: not a PEM file \(no -----BEGIN line\)$"),
        ((lab / "ca.pem", garbage, lab / "rig.key"), r"^--tls-cert \S+garbage\.pem: not a PEM certificate"),
        ((lab / "rig.pem", lab / "rig.pem", lab / "rig.key"), r"^--tls-ca \S+rig\.pem: not a CA certificate"),
        ((lab / "ca.pem", other / "rig.pem", other / "rig.key"),
         r"^--tls-cert \S+other/rig\.pem: not signed by the CA \S+certs/ca\.pem"),
        ((lab / "ca.pem", lab / "rig.pem", lab / "table.key"),
         r"^--tls-key \S+table\.key: not the private key of --tls-cert \S+rig\.pem$"),
        ((lab / "ca.pem", lab / "rig.pem", lab / "ca.pem"), r"^--tls-key \S+ca\.pem: readable by others"),
    ]
    for files, message in cases:
        with pytest.raises(TlsError, match=message):
            load_tls(*files)


def test_a_key_readable_by_others_and_an_expired_certificate(lab: Path, tmp_path: Path) -> None:
    (lab / "rig.key").chmod(0o644)
    with pytest.raises(TlsError, match=r"rig\.key: readable by others \(mode 0644\): chmod 600 "):
        load_tls(*_files(lab, "rig"))
    old = make_identity(lab, "old", days=1, now=dt.datetime(2020, 1, 1, tzinfo=dt.UTC))
    with pytest.raises(TlsError, match=r"^--tls-cert \S+old\.pem: expired on 2020-01-02 00:00 UTC$"):
        load_tls(old.ca, old.certificate, old.key)
    names = TlsOptions("rig.toml:3: network.tls.ca", "rig.toml:4: network.tls.certificate", "rig.toml:5: x")
    with pytest.raises(TlsError, match=r"^rig\.toml:4: network\.tls\.certificate \S+old\.pem: expired"):
        load_tls(old.ca, old.certificate, old.key, names=names)


# ----- rig certs make -----------------------------------------------------------------------------------------


def test_certificates_made_once_per_directory(lab: Path) -> None:
    table = x509.load_pem_x509_certificate((lab / "table.pem").read_bytes())
    ca = x509.load_pem_x509_certificate((lab / "ca.pem").read_bytes())
    table.verify_directly_issued_by(ca)
    names = table.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert [str(ip) for ip in names.get_values_for_type(x509.IPAddress)] == ["10.231.0.2"]
    for key in ("ca.key", "table.key", "rig.key"):
        assert stat.S_IMODE((lab / key).stat().st_mode) == 0o600
    again = make_identity(lab, "console", dns=("control-room.lab",))
    assert not again.made_ca and again.ca == lab / "ca.pem"  # the same CA signs every identity of the directory
    for name, kwargs, message in [("rig", {}, r"rig\.pem: exists \(a certificate is never overwritten"),
                                  ("ca", {}, r"--name 'ca'"), ("a/b", {}, r"--name 'a/b'"),
                                  ("x", {"addresses": ("10.0.0.300",)}, r"--ip '10\.0\.0\.300': not an IP address"),
                                  ("x", {"days": 0}, r"--days 0: expected 1\.\.3650")]:
        with pytest.raises(CertError, match=message):
            make_identity(lab, name, **kwargs)


def test_rig_certs_make_prints_the_options_and_the_fingerprint(tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["certs", "make", str(tmp_path / "c"), "--name", "table", "--ip", "10.231.0.2",
                                      "--json"])
    assert result.exit_code == 0, result.output
    made = json.loads(result.stdout)
    assert made["made_ca"] is True and made["key"] == str(tmp_path / "c" / "table.key")
    assert len(made["fingerprint_sha256"].split(":")) == 32
    again = CliRunner().invoke(app, ["certs", "make", str(tmp_path / "c"), "--name", "table"])
    assert again.exit_code == 2 and "table.pem: exists" in again.stderr


def test_rig_commands_refuse_a_partial_identity_in_one_line(lab: Path) -> None:
    result = CliRunner().invoke(app, ["service", "state", "--tls-ca", str(lab / "ca.pem"), "--tls-key",
                                      str(lab / "rig.key")])
    assert result.exit_code == 2
    assert result.stderr.strip().splitlines() == [
        "error: --tls-ca, --tls-key given without --tls-cert: a TLS identity is the CA, the certificate and its "
        "key together"]


# ----- the rig configuration's [network] -----------------------------------------------------------------------


def _rig_toml(folder: Path, body: str) -> Path:
    path = folder / "rig.toml"
    path.write_text("[table]\ncontroller_rate_hz = 1000\n\n" + body)
    return path


def test_the_rig_toml_names_the_tls_identity_relative_to_its_folder(lab: Path) -> None:
    folder = lab.parent
    path = _rig_toml(folder, '[network]\nca = "certs/ca.pem"\ncert = "certs/rig.pem"\nkey = "certs/rig.key"\n')
    model = TableModel.from_toml(path)
    assert (model.network.ca, model.network.cert, model.network.key) == (lab / "ca.pem", lab / "rig.pem",
                                                                         lab / "rig.key")
    assert model.network.where == (f"{path}:5: network.ca", f"{path}:6: network.cert", f"{path}:7: network.key")
    assert model == TableModel() and "network" not in model.to_dict()  # the machine's, not the table's
    assert not TableModel().network.given
    security = configured_security(LinkSecurity(), model.network)
    assert security.tls == load_tls(*_files(lab, "rig"))
    given = LinkSecurity(load_tls(*_files(lab, "table")))
    assert configured_security(given, model.network) is given  # the command line's options win


@pytest.mark.parametrize(("body", "expected"), [
    ('[network]\nkey = "certs/rig.key"\n',
     r"rig\.toml:5: network\.key: network\.key given without network\.ca and network\.cert: a TLS identity is"),
    ('[network]\nca = "certs/ca.pem"\ncert = "certs/nope.pem"\nkey = "certs/rig.key"\n',
     r"rig\.toml:6: network\.cert: this process's certificate '.*certs/nope\.pem': no such file$"),
    ('[network]\nca = "certs"\ncert = "certs/rig.pem"\nkey = "certs/rig.key"\n',
     r"rig\.toml:5: network\.ca: the lab's CA certificate '.*certs': not a regular file$"),
    ('[network]\nca = "certs/ca.pem"\ncert = "certs/rig.pem"\nkey = 3\n',
     r"rig\.toml:7: network\.key: expected the path of its private key \(a string\), got 3$"),
    ('[network]\nca = "certs/ca.pem"\ncertificate = "certs/rig.pem"\n',
     r"rig\.toml:6: network\.certificate: unknown key.*expected one of ca, cert, key, console$"),
])
def test_a_bad_network_table_is_refused_with_file_line_and_field(lab: Path, body: str, expected: str) -> None:
    with pytest.raises(TableModelError, match=expected) as raised:
        TableModel.from_toml(_rig_toml(lab.parent, body))
    assert "\n" not in str(raised.value)


def test_the_rig_toml_names_the_consoles_certificate_names_and_tokens(lab: Path) -> None:
    folder = lab.parent
    (folder / "tokens.toml").write_text("")
    path = _rig_toml(folder, '[network.console]\nhttps_cert = "certs/rig.pem"\nhttps_key = "certs/rig.key"\n'
                             'names = ["rig.lab", "10.231.0.5"]\ntokens = "tokens.toml"\n')
    network = TableModel.from_toml(path).network
    assert not network.given  # a console without a zenoh identity
    console = network.console
    assert (console.https_cert, console.https_key, console.https_dir) == (lab / "rig.pem", lab / "rig.key", None)
    assert console.names == ("rig.lab", "10.231.0.5") and console.tokens == folder / "tokens.toml"
    made = TableModel.from_toml(_rig_toml(folder, '[network.console]\nhttps_dir = "web"\n')).network.console
    assert made.https_dir == folder / "web" and made.https_cert is None  # made on first use: need not exist


@pytest.mark.parametrize(("body", "expected"), [
    ('[network.console]\nhttps_cert = "certs/rig.pem"\n',
     r"rig\.toml:5: network\.console\.https_cert: network\.console\.https_cert given without "
     r"network\.console\.https_key: the console's certificate and its key go together$"),
    ('[network.console]\nhttps_cert = "certs/rig.pem"\nhttps_key = "certs/rig.key"\nhttps_dir = "web"\n',
     r"rig\.toml:7: network\.console\.https_dir: .* give the certificate, or the folder one is made in, not both$"),
    ('[network.console]\nnames = "rig.lab"\n',
     r"rig\.toml:5: network\.console\.names: expected a list of DNS names or addresses .*, got 'rig\.lab'$"),
    ('[network.console]\ntokens = "nope.toml"\n',
     r"rig\.toml:5: network\.console\.tokens: the tokens file of operators and viewers '.*nope\.toml': no such "
     r"file$"),
    ('[network.console]\ntoken = "t.toml"\n',
     r"rig\.toml:5: network\.console\.token: unknown key.*expected one of https_cert, https_key, https_dir, names, "
     r"tokens$"),
])
def test_a_bad_console_table_is_refused_with_file_line_and_field(lab: Path, body: str, expected: str) -> None:
    with pytest.raises(TableModelError, match=expected) as raised:
        TableModel.from_toml(_rig_toml(lab.parent, body))
    assert "\n" not in str(raised.value)


def test_the_rig_toml_identity_is_checked_where_it_is_used_and_named_by_line(lab: Path, tmp_path: Path) -> None:
    other = make_identity(tmp_path / "other", "rig")  # another lab's CA signed it
    path = _rig_toml(lab.parent, f'[network]\nca = "certs/ca.pem"\ncert = "{other.certificate}"\n'
                                 f'key = "{other.key}"\n')
    sequence = tmp_path / "seq.toml"
    sequence.write_text(f'table_url = "zenoh://10.231.0.2:7447/lab"\n{TINY}\n[rig]\nconfig = "{path}"\n')
    result = CliRunner().invoke(app, ["run", str(sequence), "--yes", "-o", str(tmp_path / "s.h5")])
    assert result.exit_code == 2, result.output
    [line] = result.stderr.strip().splitlines()
    assert line.startswith(f"error: {path}:6: network.cert {other.certificate}: ") and "CA" in line
    assert not (tmp_path / "s.h5").exists()  # refused before a session file or a link


def test_rig_emulate_takes_the_rig_toml_identity_for_zenoh_only(lab: Path, key_file: Path) -> None:
    path = _rig_toml(lab.parent, '[network]\nca = "certs/ca.pem"\ncert = "certs/table.pem"\nkey = "certs/table.key"\n')
    config, _, _ = parse_args(["--listen", "zenoh://10.231.0.2:7447/lab", "--key-file", str(key_file),
                               "--rig-config", str(path)])
    assert config.security == LinkSecurity(load_tls(*_files(lab, "table")))
    config, _, _ = parse_args(["--listen", "mavlink://127.0.0.1:0", "--key-file", str(key_file),
                               "--rig-config", str(path)])
    assert config.security == LinkSecurity()  # MAVLink has no TLS: the [network] of the file does not apply
    given = load_tls(*_files(lab, "rig"))  # the options win over the file (its identity would be the table's)
    config, _, _ = parse_args(["--listen", "zenoh://127.0.0.1:7447/lab", "--key-file", str(key_file),
                               "--rig-config", str(path), "--tls-ca", str(given.ca), "--tls-cert",
                               str(given.certificate), "--tls-key", str(given.key)])
    assert config.security.tls == given
