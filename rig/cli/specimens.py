"""``rig specimens check``: the emulator's specimens characterised against the closed forms of rocking.

The measurements run in the emulator's own specimen model, so this command runs ``python -m sim_table.characterise``
as a process (``rig`` never imports ``sim_table``: the emulator stands where the table's controller would) and
passes its output and exit code on. What is measured and how: ``docs/specimens.md``.
"""

from __future__ import annotations

import subprocess
import sys
from typing import Annotated

import typer


def register(app: typer.Typer) -> None:
    """Add ``rig specimens check``."""
    specimens = typer.Typer(help="The emulator's specimens: their physics checked against the closed forms.",
                            no_args_is_help=True)
    app.add_typer(specimens, name="specimens")

    @specimens.command("check")
    def check_cmd(
        body: Annotated[list[str] | None, typer.Option(metavar="BxH", help="a body b×h [m], e.g. 0.1x0.5 "
                                                                           "(repeatable)")] = None,
        table5: Annotated[bool, typer.Option("--table5", help="the paper's seven Table V bodies")] = False,
        tilt: Annotated[float, typer.Option(help="plate tilt for the uplift accelerations [deg]")] = 5.0,
        friction: Annotated[float, typer.Option(help="friction coefficient μ between body and plate")] = 0.8,
        as_json: Annotated[bool, typer.Option("--json", help="print one JSON object")] = False,
    ) -> None:
        """Free-rocking restitution against Housner's 1 − 1.5 sin²α, the quarter period against its closed form,
        the accelerations that start rocking towards each side at the tilt against Eq. 1, and the sliding onset
        against μ, measured in the emulator's specimen model (MuJoCo, 1 ms step)."""
        args = [sys.executable, "-m", "sim_table.characterise", "--tilt", repr(tilt), "--friction", repr(friction)]
        for b in body or []:
            args += ["--body", b]
        if table5:
            args.append("--table5")
        if as_json:
            args.append("--json")
        raise typer.Exit(subprocess.run(args, check=False).returncode)
