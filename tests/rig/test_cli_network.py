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
