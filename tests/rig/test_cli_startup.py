"""A CLI that answers at once (issue 16): ``rig --help`` and the help of every command load none of the heavy
modules (numpy, scipy, numba, matplotlib, h5py, mujoco, dask, zenoh, pymavlink, canopen …); a command loads what
it uses when it runs. Checked on ``sys.modules`` in a fresh interpreter (load-independent: no wall-clock limit;
the times are measured by benchmarks/cli_startup.py)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.helpers.processes import HEAVY

pytestmark = pytest.mark.integration  # starts processes or opens sockets (tests/conftest.py)

REPO = Path(__file__).resolve().parents[2]

_PROBE = r"""
import json, sys
import typer
from typer.testing import CliRunner
from rig.cli import app

heavy = json.loads(sys.argv[1])
loaded = lambda: sorted(m for m in heavy if m in sys.modules)
report = {"import rig.cli": loaded()}
command = typer.main.get_command(app)

def paths(group, prefix):
    for name, sub in group.commands.items():
        yield [*prefix, name]
        if hasattr(sub, "commands"):  # a group (typer may vendor its own click)
            yield from paths(sub, [*prefix, name])

runner = CliRunner()
for args in [[], *paths(command, [])]:
    if args == ["emulate"]:  # becomes `python -m sim_table` (exec): its own program, timed by the benchmark
        continue
    result = runner.invoke(app, [*args, "--help"])
    report[" ".join(["rig", *args, "--help"])] = {"exit": result.exit_code, "loaded": loaded(),
                                                  "usage": "Usage" in result.output}
print(json.dumps(report))
"""


def test_help_of_rig_and_of_every_command_imports_no_heavy_module() -> None:
    out = subprocess.run([sys.executable, "-c", _PROBE, json.dumps(HEAVY)], capture_output=True, text=True,
                         cwd=REPO, timeout=300, check=True).stdout
    report = json.loads(out)
    assert report.pop("import rig.cli") == []
    assert len(report) >= 12 and {"rig --help", "rig sessions recover --help", "rig records show --help"} <= set(report)
    for help_of, seen in report.items():
        assert seen["exit"] == 0 and seen["usage"], help_of
        assert seen["loaded"] == [], f"{help_of} imported {seen['loaded']}"


def test_a_command_pays_only_for_what_it_uses(tmp_path: Path) -> None:
    """``rig records show`` of a text file reads it without the models, numba, scipy or matplotlib."""
    record = tmp_path / "r.txt"
    record.write_text("# dt = 0.01\n# units = g\n0.0\n0.1\n-0.05\n")
    probe = ("import json, sys\nfrom typer.testing import CliRunner\nfrom rig.cli import app\n"
             f"result = CliRunner().invoke(app, ['records', 'show', {str(record)!r}, '--json'])\n"
             "print(json.dumps({'exit': result.exit_code, 'loaded': sorted(m for m in json.loads(sys.argv[1]) "
             "if m in sys.modules)}))")
    out = json.loads(subprocess.run([sys.executable, "-c", probe, json.dumps(HEAVY)], capture_output=True, text=True,
                                    cwd=REPO, timeout=300, check=True).stdout)
    assert out["exit"] == 0
    assert "rig.records" in out["loaded"] and "numpy" in out["loaded"]  # what it uses …
    assert not {"numba", "scipy", "matplotlib", "analysis.simulate", "rig.orchestrator", "zenoh"} & set(out["loaded"])
