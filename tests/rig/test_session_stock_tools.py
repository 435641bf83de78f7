"""The session file read by readers that are not the project's: Debian's hdf5-tools 1.10 (``h5dump``, ``h5ls``,
``h5clear``; ``apt-get install hdf5-tools``). Units on every field of every dataset, and the live reading the docs
describe (docs/orchestrator.md, *Reading a session with other tools*)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from rig.session import SessionLog

pytestmark = [pytest.mark.integration,
              pytest.mark.skipif(shutil.which("h5dump") is None or shutil.which("h5clear") is None,
                                 reason="Debian's hdf5-tools (h5dump, h5ls, h5clear) are not installed: "
                                        "apt-get install -y hdf5-tools")]

SHEET = {"0": {"model": "PCB 356A16", "serial": "LW231455", "sensitivity": 100.0, "sensitivity_unit": "mV/g",
              "range": 5.0, "range_unit": "g", "calibrated": "2026-01-15", "due": "2027-01-15",
              "place_m": [0.3, -0.2, 0.05], "axes": ["+x", "-y", "+z"]}}
BODIES = [{"body_id": 1, "b": 0.1, "h": 0.5, "depth": 0.1, "mass": 5.0, "x": 0.0, "y": 0.0, "name": "B1"}]
ENV = {**os.environ, "HDF5_USE_FILE_LOCKING": "FALSE"}


def _begin(log: SessionLog) -> object:
    run = log.begin_run(0, record="test:rest", scale_factor=1.0, angle_deg=4.0, commanded=np.zeros((2, 7)),
                        bodies=BODIES, sensors=["0"], attrs={"rate": 1000.0})
    run.append_accel("0", np.arange(10) / 1000.0, np.zeros((10, 3)))
    run.add_event(0.0, "state: streaming")
    run.add_fault(0.1, "underrun", "setpoint buffer empty")
    run.add_detection(0.2, 1, 1, "sensor")
    return run


def _tool(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, capture_output=True, text=True, env=ENV, timeout=60)


def _widths(dump: str) -> dict[str, tuple[int, str | None]]:
    """{dataset name: (fields or columns, its units attribute or None)} of ``h5dump -A`` output."""
    out = {}
    blocks = re.split(r'\n\s*DATASET "', dump)[1:]
    for block in blocks:
        name = block.split('"', 1)[0]
        head = block.split("DATASPACE", 1)[0]
        if "H5T_COMPOUND" in head:
            width = len(re.findall(r'"\w+";', head))
        else:
            width = int(re.search(r"DATASPACE\s+SIMPLE \{ \( \d+, (\d+) \)", block).group(1))  # type: ignore[union-attr]
        units = re.search(r'ATTRIBUTE "units" \{.*?\(0\): "([^"]*)"', block, re.S)
        out[name] = (width, units.group(1) if units else None)
    return out


def test_h5dump_shows_units_on_every_field(tmp_path: Path) -> None:
    path = tmp_path / "session.h5"
    with SessionLog.create(path, {}, {"name": "stock"}, "1.0") as log:
        _begin(log).end("completed")  # type: ignore[attr-defined]
    dump = _tool("h5dump", "-A", str(path))
    assert dump.returncode == 0, dump.stderr
    widths = _widths(dump.stdout)
    assert {"commanded", "pose", "0", "1", "detections", "bodies", "faults", "events"} <= set(widths)
    for name, (width, units) in widths.items():
        assert units is not None, f"{name}: no units attribute"
        assert len(units.split(",")) == width and all(units.split(",")), (name, width, units)
    assert re.search(r'ATTRIBUTE "attribute_units" \{.*?"rate": "Hz"', dump.stdout, re.S)


def test_stock_tools_read_a_sensors_place_in_a_cleared_copy_during_a_run(tmp_path: Path) -> None:
    path, copy = tmp_path / "session.h5", tmp_path / "snapshot.h5"
    with SessionLog.create(path, {"sensors": SHEET}, {"name": "stock"}, "1.0") as log:
        assert _tool("h5ls", "-r", str(path)).returncode == 0  # between runs: the file as it is
        run = _begin(log)
        time.sleep(0.7)  # one flush interval: the samples are on disk
        assert _tool("h5ls", "-r", str(path)).returncode != 0  # open for SWMR writing: not without SWMR reading
        shutil.copyfile(path, copy)
        assert _tool("h5clear", "-s", str(copy)).returncode == 0  # the copy's status flags, never the original's
        listed = _tool("h5ls", "-r", str(copy))
        place = _tool("h5dump", "-a", "/runs/0001/accel/0/place_m", "-a", "/runs/0001/accel/0/axes", str(copy))
        run.end("completed")  # type: ignore[attr-defined]
    assert listed.returncode == 0, listed.stderr
    assert re.search(r"/runs/0001/accel/0\s+Dataset \{10/Inf, 4\}", listed.stdout), listed.stdout
    assert place.returncode == 0, place.stderr
    assert re.search(r"\(0\): 0\.3, -0\.2, 0\.05", place.stdout) and '(0): "+x,-y,+z"' in place.stdout, place.stdout
