"""The lab network's options on ``rig run`` and ``rig serve`` (docs/lab-network.md), in process with typer's
CliRunner: what each command is given reaches what it starts; a bad option is refused saying which."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from rig.cli import app
from tests.helpers.sequences import TINY


def _sequence(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    return path


def test_rig_run_gives_its_console_the_https_names_and_tokens(tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    import rig.cli.with_console
    from rig.console import WebAccess

    given: dict[str, Any] = {}

    def run_with_console(http: str, sequence: Path | None, **options: Any) -> int:
        given.update(options, http=http)
        return 0

    monkeypatch.setattr(rig.cli.with_console, "run_with_console", run_with_console)
    done = CliRunner().invoke(app, ["run", str(_sequence(tmp_path)), "--emulate", "--yes", "--console",
                                    "10.231.0.1:8443", "--https-dir", "web", "--tokens", "tokens.toml",
                                    "--http-name", "rig.lab", "--http-name", "10.231.0.5"])
    assert done.exit_code == 0, done.output
    assert given["http"] == "10.231.0.1:8443"
    assert given["access"] == WebAccess(("rig.lab", "10.231.0.5"), Path("tokens.toml"), None, None, Path("web"))


def test_the_console_options_without_a_console_are_refused(tmp_path: Path) -> None:
    done = CliRunner().invoke(app, ["run", str(_sequence(tmp_path)), "--emulate", "--yes", "--tokens", "t.toml"])
    assert done.exit_code == 2
    assert "are the console's: give --console HOST:PORT too" in done.output


# ----- [network] of the rig TOML on rig serve and rig run --service / --resume ---------------------------------


def _identity(folder: Path, name: str) -> str:
    """A TLS identity made in ``folder/certs`` and the rig TOML's ``[network]`` naming it (paths relative)."""
    from rig.certs import make_identity

    make_identity(folder / "certs", name)
    return (f'[network]\nca = "certs/ca.pem"\ncert = "certs/{name}.pem"\nkey = "certs/{name}.key"\n')


def _rig_toml(folder: Path, name: str, text: str | None = None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "rig.toml"
    path.write_text(_identity(folder, name) if text is None else text)
    return path


BAD_NETWORK = '# the lab network\n[network]\nca = 3\ncert = "c.pem"\nkey = "k.pem"\n'
"""A ``[network]`` whose ``ca`` (line 3) is no path."""


def _refused_at_line_3(done: Any, path: Path) -> None:
    assert done.exit_code == 2, done.output
    assert f"{path}:3: network.ca: expected the path of the lab's CA certificate (a string), got 3" in done.output
    assert "Traceback" not in done.output


def test_rig_serve_takes_its_identity_from_the_rig_toml(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import rig.cli.serve

    given: list[Any] = []
    monkeypatch.setattr(rig.cli.serve, "serve", lambda *args: given.append(args[6]))
    config = _rig_toml(tmp_path / "service", "service")
    done = CliRunner().invoke(app, ["serve", "--listen", "tls/10.231.0.1:7448", "--rig-config", str(config)])
    assert done.exit_code == 0, done.output
    assert given[0].tls.certificate == tmp_path / "service" / "certs" / "service.pem"
    # the command line wins
    other = _rig_toml(tmp_path / "other", "other")
    done = CliRunner().invoke(app, ["serve", "--listen", "tls/10.231.0.1:7448", "--rig-config", str(config),
                                    "--tls-ca", str(other.parent / "certs" / "ca.pem"), "--tls-cert",
                                    str(other.parent / "certs" / "other.pem"), "--tls-key",
                                    str(other.parent / "certs" / "other.key")])
    assert done.exit_code == 0, done.output
    assert given[1].tls.certificate == other.parent / "certs" / "other.pem"


def test_rig_serve_refuses_a_bad_network_with_file_and_line(tmp_path: Path) -> None:
    config = _rig_toml(tmp_path, "service", BAD_NETWORK)
    _refused_at_line_3(CliRunner().invoke(app, ["serve", "--listen", "tls/10.231.0.1:7448", "--rig-config",
                                                str(config)]), config)


def test_rig_run_service_takes_the_identity_of_the_sequence_or_of_rig_config(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import rig.cli.serve

    given: list[Any] = []

    def drive_service(connect: str, sequence: Path | None, **options: Any) -> int:
        given.append(options["security"])
        return 0

    monkeypatch.setattr(rig.cli.serve, "drive_service", drive_service)
    _rig_toml(tmp_path, "rig")
    sequence = tmp_path / "tiny.toml"
    sequence.write_text(TINY + '\n[rig]\nconfig = "rig.toml"\n')
    run = ["run", str(sequence), "--service", "tls/10.231.0.1:7448", "--yes"]
    done = CliRunner().invoke(app, run)
    assert done.exit_code == 0, done.output
    assert given[0].tls.certificate == tmp_path / "certs" / "rig.pem"
    operator = _rig_toml(tmp_path / "operator", "operator")  # --rig-config wins over the sequence's
    done = CliRunner().invoke(app, [*run, "--rig-config", str(operator)])
    assert done.exit_code == 0, done.output
    assert given[1].tls.certificate == operator.parent / "certs" / "operator.pem"
    bad = _rig_toml(tmp_path / "bad", "bad", BAD_NETWORK)
    _refused_at_line_3(CliRunner().invoke(app, [*run, "--rig-config", str(bad)]), bad)


def test_rig_run_resume_on_a_zenoh_table_takes_the_identity_of_rig_config(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A session file does not keep the machine's identity: ``--rig-config`` gives it to the resumed session."""
    import rig.orchestrator.setup
    from rig.orchestrator.setup import TableUnreachableError
    from rig.sequence import load_sequence
    from tests.helpers.sequences import new_log

    sequence = tmp_path / "tiny.toml"
    sequence.write_text(TINY)
    session = tmp_path / "session.h5"
    new_log(load_sequence(sequence), session).close()
    given: list[dict[str, Any]] = []

    def table_for(*args: Any) -> Any:
        given.append(args[5])
        raise TableUnreachableError("not reached in this test")

    monkeypatch.setattr(rig.orchestrator.setup, "table_for", table_for)
    config = _rig_toml(tmp_path / "operator", "operator")
    resume = ["run", "--resume", str(session), "--table", "zenoh://10.231.0.2:7447/lab", "--yes"]
    done = CliRunner().invoke(app, [*resume, "--rig-config", str(config)])
    assert done.exit_code == 2 and "not reached in this test" in done.output, done.output
    assert given[0]["tls"].certificate == config.parent / "certs" / "operator.pem"
    bad = _rig_toml(tmp_path / "bad", "bad", BAD_NETWORK)
    _refused_at_line_3(CliRunner().invoke(app, [*resume, "--rig-config", str(bad)]), bad)


CONSOLE_TOML = ('[network.console]\nhttps_dir = "web"\nnames = ["rig.lab"]\ntokens = "tokens.toml"\n')
"""A ``[network.console]``: the console's certificate made in ``web``, reached as rig.lab, a tokens file."""


def test_rig_serve_http_and_rig_run_console_take_the_console_from_the_rig_toml(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import rig.cli.serve
    import rig.cli.with_console
    from rig.console import WebAccess

    config = _rig_toml(tmp_path, "rig", CONSOLE_TOML)
    (tmp_path / "tokens.toml").write_text("")
    configured = WebAccess(("rig.lab",), tmp_path / "tokens.toml", None, None, tmp_path / "web")
    served: list[Any] = []
    monkeypatch.setattr(rig.cli.serve, "serve", lambda *args: served.append(args[7]))
    done = CliRunner().invoke(app, ["serve", "--http", "10.231.0.1:8443", "--rig-config", str(config)])
    assert done.exit_code == 0, done.output
    assert served == [configured]

    given: list[Any] = []

    def run_with_console(http: str, sequence: Path | None, **options: Any) -> int:
        given.append(options["access"])
        return 0

    monkeypatch.setattr(rig.cli.with_console, "run_with_console", run_with_console)
    sequence = tmp_path / "tiny.toml"
    sequence.write_text(TINY + '\n[rig]\nconfig = "rig.toml"\n')
    run = ["run", str(sequence), "--emulate", "--yes", "--console", "10.231.0.1:8443"]
    assert CliRunner().invoke(app, run).exit_code == 0
    # the command line wins, the HTTPS certificate as a whole
    assert CliRunner().invoke(app, [*run, "--http-name", "10.231.0.5", "--https-cert", "c.pem", "--https-key",
                                    "c.key"]).exit_code == 0
    assert given == [configured, WebAccess(("10.231.0.5",), tmp_path / "tokens.toml", Path("c.pem"), Path("c.key"),
                                           None)]


def test_rig_console_takes_its_identity_and_console_from_the_rig_toml(tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    import rig.console
    from rig.console import WebAccess

    (tmp_path / "tokens.toml").write_text("")
    config = _rig_toml(tmp_path, "rig")
    config.write_text(config.read_text() + CONSOLE_TOML)
    given: list[dict[str, Any]] = []
    monkeypatch.setattr(rig.console, "serve_console", lambda connect, http, **options: given.append(options))
    done = CliRunner().invoke(app, ["console", "--connect", "tls/10.231.0.1:7448", "--http", "10.231.0.1:8443",
                                    "--rig-config", str(config)])
    assert done.exit_code == 0, done.output
    assert given[0]["security"].tls.certificate == tmp_path / "certs" / "rig.pem"
    assert given[0]["access"] == WebAccess(("rig.lab",), tmp_path / "tokens.toml", None, None, tmp_path / "web")


def test_rig_run_console_gives_its_service_the_identity_for_a_zenoh_table(tmp_path: Path,
                                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """``rig run --console`` plays through a service of its own on loopback: the table's TLS identity (here the
    sequence's ``[rig] config``) is given to that service for its zenoh table, not for its own loopback endpoint."""
    import rig.service
    from rig.service import ServiceError

    given: list[dict[str, Any]] = []

    def service(endpoint: str, **options: Any) -> Any:
        given.append({"endpoint": endpoint, **options})
        raise ServiceError("not started in this test")

    import rig.cli.with_console

    monkeypatch.setattr(rig.service, "OrchestratorService", service)
    monkeypatch.setattr(rig.cli.with_console, "_free_endpoint", lambda: "tcp/127.0.0.1:7447")  # no socket
    _rig_toml(tmp_path, "rig")
    sequence = tmp_path / "tiny.toml"
    sequence.write_text('table_url = "zenoh://10.231.0.2:7447/lab"\n' + TINY + '\n[rig]\nconfig = "rig.toml"\n')
    done = CliRunner().invoke(app, ["run", str(sequence), "--yes", "--console", "127.0.0.1:8080"])
    assert done.exit_code == 2 and "not started in this test" in done.output, done.output
    assert given[0]["endpoint"] == "tcp/127.0.0.1:7447" and "security" not in given[0]
    assert given[0]["table_security"].tls.certificate == tmp_path / "certs" / "rig.pem"
