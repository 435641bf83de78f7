"""``rig specimens check``: the emulator's specimens characterised against the closed forms of rocking.

The measurements run in the emulator's own specimen model, so this command runs ``python -m sim_table.characterise``
as a process (``rig`` never imports ``sim_table``: the emulator stands where the table's controller would) and
passes its output and exit code on. What is measured and how: ``docs/specimens.md``.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Annotated

import typer

from rig.cli._common import fail


def register(app: typer.Typer) -> None:
    """Add ``rig specimens check``."""
    specimens = typer.Typer(help="The emulator's specimens: their physics checked against the closed forms.",
                            no_args_is_help=True)
    app.add_typer(specimens, name="specimens")

    @specimens.command("check")
    def check_cmd(
        body: Annotated[list[str] | None, typer.Option(
            metavar="BxH[;restitution=E][;cg=BCG,HCG]",
            help="a body b×h [m], e.g. 0.1x0.5, optionally its measured restitution: '0.1x0.5;restitution=0.85', "
                 "and its centre of gravity (b_cg from the base's -x corner, h_cg above the base [m]): "
                 "'0.099x0.493;cg=0.0515,0.243' (repeatable)")] = None,
        table5: Annotated[bool, typer.Option("--table5", help="the paper's seven Table V bodies")] = False,
        sequence: Annotated[Path | None, typer.Option(metavar="SEQUENCE.toml",
                                                      help="the bodies of a sequence file, with their friction and "
                                                           "measured restitution")] = None,
        tilt: Annotated[float, typer.Option(help="plate tilt for the uplift accelerations [deg]")] = 5.0,
        friction: Annotated[float, typer.Option(help="friction coefficient μ between body and plate")] = 0.8,
        as_json: Annotated[bool, typer.Option("--json", help="print one JSON object")] = False,
    ) -> None:
        """On each side of each body: the free-rocking restitution against Housner's (1 − 1.5 sin²α, per impact
        direction for a centre of mass off the middle; or the body's measured value, set with
        ``--body "BxH;restitution=E"`` or in the sequence), the quarter period against its closed form, the
        acceleration that starts rocking towards that side at the tilt against Eq. 1 and the slenderness it shows
        against the body's α+ / α−; and the sliding onset against μ, measured in the emulator's specimen model
        (MuJoCo, 1 ms step)."""
        args = [sys.executable, "-m", "sim_table.characterise", "--tilt", repr(tilt), "--friction", repr(friction)]
        for b in body or []:
            args += ["--body", b]
        if sequence is not None:
            from rig.emulator import specimen_flags
            from rig.sequence import SequenceError, load_sequence

            try:
                args += specimen_flags(load_sequence(sequence).bodies)
            except SequenceError as exc:
                fail(str(exc))
        if table5:
            args.append("--table5")
        if as_json:
            args.append("--json")
        raise typer.Exit(subprocess.run(args, check=False).returncode)
