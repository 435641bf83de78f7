"""Names, types and units of the session file, schema ``shaketable-rig/session/1`` (docs/architecture.md §7).

Root attributes: ``schema``, ``software_version``, ``created`` (ISO 8601, UTC), ``rig_config`` and ``sequence`` (JSON
text), and ``table`` (JSON text, where ``rig run`` played it: ``{"url": …}`` or ``{"emulate": true, "speed": …}``,
``rig.orchestrator.setup.TableChoice``; absent in files written by tools that play on no table). ``/runs/<NNNN>/``:
one group per run *attempt*, numbered 0001, 0002, … in the order the runs began (a re-run of an interrupted plan entry
is a new group; the old one stays, status ``interrupted``).

Run attributes: ``record`` (text), ``scale_factor`` (float), ``angle_deg`` (float, degrees), ``plan_index`` (int,
index into the sequence's plan), ``attempt`` (int, 1 for the first run of that plan index), ``started`` and ``ended``
(ISO 8601 UTC; ``ended`` is ``""`` while the run is in progress), ``status``, ``sensors`` (JSON list of the
accelerometer names), ``attribute_units`` (JSON: the units of the numeric run attributes present, `RUN_ATTR_UNITS`:
``rate`` in Hz, …), at the end ``clipped`` and ``tilt_clipped`` (JSON {sensor or body: samples at or beyond the full
scale of its calibration sheet}), plus any extra attributes given by the caller.

``status``: one of `FINAL_STATUSES` (docs/orchestrator.md §The session file), or ``"running"`` while recorded (until
`SessionLog.resume` turns a dead writer's into ``"interrupted"``), kept with ``ended`` as fixed-length UTF-8 so the
final values replace them in one object-header page (`rig.session.atomic`); `read_session` returns ``str``.

Run datasets (all float64 unless said; time ``t`` in seconds on the run's clock):

* ``commanded`` (N, 7): t, surge, sway, heave [m], roll, pitch, yaw [rad];
* ``accel/<sensor>`` (M, 4): t, ax, ay, az [m/s², plate frame];
* ``tilt/<body_id>`` (L, 2): t, angle [rad]: the body's rocking angle from its tilt sensor, relative to the plate,
  > 0 when its top has moved towards +x (the low side); one per body (empty over CANopen; absent in older files);
* ``pose`` (K, 7): measured table pose from the controller's status feedback, columns as ``commanded``;
  ``following_error`` (J, 7): t, leg1 … leg6 [m]: commanded minus measured length, from the statuses that carry it;
* ``detections``: compound `DETECTION`: t [s], body_id, direction (+1 towards the low side, −1 towards the
  high side, 0 none), source (``"sensor"`` | ``"operator"``);
* ``bodies``: compound `BODY`: body_id, b, h, depth [m], mass [kg], x, y [m, plate frame], name, b_cg, h_cg [m]:
  the centre of gravity from the base's −x corner and above the base (``analysis.Body``; NaN: not given, the middle);
* ``faults``: compound `FAULT`: t [s], name, detail; ``events``: compound `EVENT`: t [s], text;
* ``checksums``: compound `rig.session.checksums.CHECKSUM`: dataset, first_row, rows, crc32 of each block of rows
  written to the datasets above (absent in files written before checksums: "not checksummed").

Every dataset has attributes ``columns`` and ``units``, one entry per column or field, in order, comma-separated
(``1`` dimensionless, ``-`` `NOT_A_QUANTITY`); a calibrated sensor's ``accel/<sensor>`` and a body's ``tilt/<body_id>``
carry their sheets (docs/sensors.md). Compound text fields are fixed-length UTF-8 (``bytes`` in h5py), cut at the
field size (at a character boundary). ``/runs/<NNNN>/analysis/`` is left to ``rig analyze``.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime

import h5py
import numpy as np

SCHEMA = "shaketable-rig/session/1"

RUNNING = "running"
#: Statuses a run can end with.
FINAL_STATUSES = ("completed", "degraded", "aborted", "interrupted", "refused", "skipped")
#: Final statuses whose plan entry is done (not run again when a session resumes).
DONE_STATUSES = frozenset({"completed", "refused", "skipped"})
DETECTION_SOURCES = ("sensor", "operator")

#: Attributes every run group has (extra caller attributes may not reuse these names).
RUN_ATTRS = ("record", "scale_factor", "angle_deg", "status", "started", "ended", "plan_index", "attempt",
             "sensors", "attribute_units", "clipped", "tilt_clipped")

ACCEL_COLUMNS = ("t", "ax", "ay", "az")
ACCEL_UNITS = ("s", "m/s^2", "m/s^2", "m/s^2")
TILT_COLUMNS = ("t", "angle")
TILT_UNITS = ("s", "rad")
POSE_COLUMNS = ("t", "surge", "sway", "heave", "roll", "pitch", "yaw")
POSE_UNITS = ("s", "m", "m", "m", "rad", "rad", "rad")
FOLLOWING_ERROR_COLUMNS = ("t", "leg1", "leg2", "leg3", "leg4", "leg5", "leg6")
FOLLOWING_ERROR_UNITS = ("s", "m", "m", "m", "m", "m", "m")

#: Rows per chunk: 4096 × 4 × 8 B = 128 KiB for an accelerometer (about 4 s at 1 kHz).
ACCEL_CHUNK = 4096
POSE_CHUNK = 2048
TILT_CHUNK = 2048
TABLE_CHUNK = 128

SOURCE_LEN, NAME_LEN, TEXT_LEN = 16, 64, 512


def _text(n: int) -> np.dtype:
    return h5py.string_dtype("utf-8", n)


DETECTION = np.dtype([("t", "<f8"), ("body_id", "<i4"), ("direction", "i1"), ("source", _text(SOURCE_LEN))])
BODY = np.dtype([("body_id", "<i4"), ("b", "<f8"), ("h", "<f8"), ("depth", "<f8"), ("mass", "<f8"),
                 ("x", "<f8"), ("y", "<f8"), ("name", _text(NAME_LEN)), ("b_cg", "<f8"), ("h_cg", "<f8")])
FAULT = np.dtype([("t", "<f8"), ("name", _text(NAME_LEN)), ("detail", _text(TEXT_LEN))])
EVENT = np.dtype([("t", "<f8"), ("text", _text(TEXT_LEN))])

NOT_A_QUANTITY = "-"
"""The unit of a field that is no quantity (text, an identifier); ``"1"`` is a dimensionless number."""
#: Units of the compound datasets' fields, in field order (attribute ``units``, as the arrays').
DETECTION_UNITS = ("s", NOT_A_QUANTITY, "1", NOT_A_QUANTITY)
BODY_UNITS = (NOT_A_QUANTITY, "m", "m", "m", "kg", "m", "m", NOT_A_QUANTITY, "m", "m")
FAULT_UNITS = ("s", NOT_A_QUANTITY, NOT_A_QUANTITY)
EVENT_UNITS = ("s", NOT_A_QUANTITY)
#: Units of the numeric run attributes a run may have (run attribute ``attribute_units``, JSON).
RUN_ATTR_UNITS = {"scale_factor": "1", "angle_deg": "deg", "rate": "Hz", "corner_frequency": "Hz",
                  "record_start": "s", "plan_index": "1", "attempt": "1", "repetition": "1"}


def fixed_text(text: str, size: int) -> bytes:
    """UTF-8 of ``text`` cut to at most ``size`` bytes without splitting a character."""
    raw = text.encode("utf-8")
    if len(raw) <= size:
        return raw
    return raw[:size].decode("utf-8", "ignore").encode("utf-8")


def iso_now() -> str:
    """The current UTC time, ISO 8601 with milliseconds (``2026-05-09T07:35:25.123+00:00``)."""
    return datetime.now(UTC).isoformat(timespec="milliseconds")


def run_name(number: int) -> str:
    """Group name of the ``number``-th run (1-based): ``"0001"``."""
    return f"{number:04d}"


def finite(value: float, what: str) -> float:
    """``value`` as a float, or ValueError naming ``what`` if it is not a finite number."""
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"{what} is {value!r}; expected a finite number")
    return number
