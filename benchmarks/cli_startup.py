"""Benchmark: how fast the ``rig`` command line answers (issue 16: ``rig --help`` took 1.8 s, ``rig simulate …``
2.2 s, mostly imports; the target is ≤ 0.3 s for ``rig --help`` and every command's help).

Each command is run as a whole process ``--repeat`` times (alternating, so that load changes hit all alike) and
its minimum and median wall times are reported, beside baselines measured in the same run: ``python -c pass``
(the interpreter's own start), ``import typer`` (the CLI framework) and ``import numpy`` (one heavy import a
help must not pay). The pre-change figures are the issue's (1.8 s and 2.2 s; they cannot be re-measured here).
Also prints the ten slowest modules of ``python -X importtime -c "import rig.cli"``.

Prints one JSON object. Usage: ``python benchmarks/cli_startup.py [--repeat N]`` (run on a quiet machine: the
figures are wall times).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TARGET_SECONDS = 0.3
BEFORE = {"rig --help": 1.8, "rig simulate ...": 2.2}

BASELINES = {"python -c pass": ["-c", "pass"], "import typer": ["-c", "import typer"],
             "import numpy": ["-c", "import numpy"]}
HELPS = ["--help", "simulate --help", "study --help", "prepare --help", "design --help", "run --help",
         "serve --help", "analyze --help", "report --help", "records --help", "records show --help",
         "sessions --help", "sessions list --help", "sessions recover --help", "service state --help"]


def _time(argv: list[str]) -> float:
    t0 = time.perf_counter()
    done = subprocess.run(argv, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    if done.returncode not in (0, 2):  # 2: the missing-file cases' usage error, timed on purpose
        raise subprocess.CalledProcessError(done.returncode, argv)
    return time.perf_counter() - t0


def _importtime() -> list[dict[str, object]]:
    """The ten modules with the largest cumulative import time [ms] under ``import rig.cli``."""
    err = subprocess.run([sys.executable, "-X", "importtime", "-c", "import rig.cli"], cwd=REPO, text=True,
                         capture_output=True, check=True).stderr
    rows: list[tuple[float, str]] = []
    for line in err.splitlines():
        parts = line.removeprefix("import time:").split("|")
        if len(parts) == 3 and parts[1].strip().isdigit():
            rows.append((int(parts[1]) / 1000, parts[2].strip()))
    return [{"module": name, "cumulative_ms": ms} for ms, name in sorted(rows, reverse=True)[:10]]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        record = Path(scratch) / "r.txt"
        record.write_text("# dt = 0.01\n# units = g\n" + "0.01\n-0.02\n" * 500)
        cases: dict[str, list[str]] = {name: [sys.executable, *argv] for name, argv in BASELINES.items()}
        rig = [sys.executable, "-m", "rig.cli"]
        cases.update({f"rig {h}": [*rig, *h.split()] for h in HELPS})
        cases["rig records show FILE --json"] = [*rig, "records", "show", str(record), "--json"]
        cases["rig simulate FILE --body 0.1x0.5"] = [*rig, "simulate", str(record), "--body", "0.1x0.5", "--json"]
        for missing in (["report", "nope.h5"], ["sessions", "show", "nope.h5"], ["run", "--resume", "nope.h5"]):
            cases[f"rig {' '.join(missing)} (missing: exit 2)"] = [*rig, *missing]  # issue 22: said at once
        times: dict[str, list[float]] = {name: [] for name in cases}
        for argv in cases.values():  # warm the file cache and numba's compiled-kernel cache once
            _time(argv)
        for _ in range(args.repeat):
            for name, argv in cases.items():
                times[name].append(_time(argv))
    figures = {name: {"min_s": round(min(t), 3), "median_s": round(statistics.median(t), 3)}
               for name, t in times.items()}
    helps = {name: f for name, f in figures.items() if name.endswith("--help")}
    print(json.dumps({
        "unit": "s (wall time of the whole process)",
        "repeat": args.repeat,
        "target_help_s": TARGET_SECONDS,
        "before_issue16_s": BEFORE,
        "figures": figures,
        "slowest_help_median_s": max(f["median_s"] for f in helps.values()),
        "helps_within_target_by_median": all(f["median_s"] <= TARGET_SECONDS for f in helps.values()),
        "import_rig_cli_slowest_modules_ms": _importtime(),
    }, indent=1))


if __name__ == "__main__":
    main()
