"""Shared fixtures (kept small on purpose)."""

from __future__ import annotations

import pytest
import typer

from analysis import Body
from rig.cli_records import register as register_records


@pytest.fixture
def v_body() -> Body:
    """The VALIDATION.md block: p = 2 rad/s, α = 0.2 rad (b ≈ 0.729 m, h ≈ 3.61 m)."""
    return Body.from_p_alpha(2.0, 0.2)


@pytest.fixture(scope="module")
def app() -> typer.Typer:
    """A Typer app with only the ``records`` command group mounted (what `rig records …` runs)."""
    app = typer.Typer()

    @app.callback()
    def main() -> None:
        """Test root."""

    register_records(app)
    return app
