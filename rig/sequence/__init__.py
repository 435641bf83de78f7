"""Sequence files (TOML): what a session on the table runs (docs/architecture.md §4; the file: docs/sequence-files.md).

A sequence names the table connection, the rig configuration, the bodies and their places on the plate,
the plate angles, the records with their scale policy, the repetitions and the operator's steps. It is
checked before anything moves: `load_sequence` checks types, keys, ranges and placements; `Sequence.check`
resolves every record, checks that every body can stand at every angle (β < α) and prepares every drive
against the table model. Every error is a `SequenceError` ``FILE:LINE: key.path: what is wrong, expected …``
(list items counted from 1: ``bodies[2].h``, ``records[3].scale``; a missing top-level key at line 1).

Units are SI unless the key says otherwise: lengths in metres, mass in kg, ``_deg`` degrees, ``_s``
seconds, ``_hz`` Hz. Top-level keys come first: in TOML every key after a ``[section]`` belongs to it::

    name = "quick"                            # default: the file's name without .toml
    description = "demo and CI"
    table_url = "mavlink://127.0.0.1:14600"   # optional: the table controller (else given at run time)
    repetitions = 1                           # runs of each record at each angle
    polarity = "both"                         # "as recorded" (default), "negated", or "both": each record
                                              # also played negated (its fall-line component × −1)
    angles_deg = [0, 4]                       # plate tilts β, run in this order; 0 ≤ β ≤ the tilt limit
    records = [                               # at every angle, in this order
        "fema-farfield:KOBE/NIS000",          # SUITE:NAME, library:NAME, a record file or H1+H2[+UP]
        { record = "fema-nearfield:NORTHR/RRS_032", scale = 0.3, window_s = [1, 6], corner_hz = 1.0 },
        { record = "data/elcentro.txt", dt_s = 0.02, units = "g" },   # paths from this file's folder
    ]
    records_from = { suite = "fema", strongest = 25 }   # optional: the 25 largest-PGA components

    [rig]                                     # optional: default Table IV and the default hexapod
    config = "rig-table4.toml"                # a rig configuration file (from this file's folder), or
                                              # inline [rig.table], [rig.limits.surge], [rig.hexapod] …

    [plate]
    size_m = [3.0, 3.0]                       # usable plate along x (fall line) and y; default 3 x 3 m

    [drive]                                   # drive preparation for every record
    settle_s = 1.0                            # held at the tilt before and after the motion
    corner_hz = 1.0                           # fixed high-pass corner; default automatic (as rig prepare)
    headroom_pct = 10                         # margin the scale factor leaves on every limit (default 0)

    [operator]
    place_bodies = "Place the bodies at their marks ({angle_deg:g}°)"   # also {bodies}, {sequence}
    confirm_before_run = true                 # wait for the operator before each run moves
    ask_detections = false                    # ask which bodies overturned and which way

    [limit_detectors.accel.x]                 # optional: replaces the rig's detector of this channel
    abort_high_g = 0.5                        # (analysis/table/limit_detectors.py, docs/limits.md)

    [[bodies]]                                # one table per body; body_id 1, 2, … in file order
    table5 = 4                                # the paper's Table V body 4 (b, h, depth, mass, b_cg, h_cg) …
    x = 0.0                                   # centre of the base on the plate, +x downhill [m]
    y = -0.2
    [[bodies]]
    name = "B2"                               # … or its dimensions; name default "body N" / "T5-N"
    b = 0.049                                 # base width along the fall line [m]
    h = 0.200                                 # height [m]
    depth = 0.109                             # along the plate's y [m]
    mass = 0.56                               # [kg]
    b_cg = 0.025                              # centre of gravity from the -x (uphill) corner [m], optional …
    h_cg = 0.100                              # … and above the base [m] (default b/2, h/2)
    x = 0.0
    y = 0.2
    friction = 0.8                            # μ body–plate, default 0.8
    restitution = 0.85                        # measured in the lab, optional: the emulated specimen reproduces it

Scale policy (``scale``): ``"table"`` (default) is the largest factor ≤ 1 that keeps the drive inside the
table's limits, as ``rig prepare``; a number in (0, 1] is a fixed factor, refused if the drive then leaves
the table. ``window_s = [t0, t1]`` plays only that part of the record (seconds from its first sample); the
drive preparation tapers its ends and brings the table to rest. ``records_from`` ranks a suite's components
by PGA (`rig.sequence.records`). Bases must lie inside the plate and must not overlap (touching is allowed).

    from rig.sequence import load_sequence
    seq = load_sequence("examples/quick.toml")
    seq.check()                               # before anything moves
    for run in seq.plan():                    # per angle, per record, per repetition
        drive = seq.prepare(run)              # the run's drive, or SequenceError with the reason
"""

from .model import (
    AS_RECORDED,
    BOTH,
    DEFAULT_FRICTION,
    DEFAULT_PLATE,
    NEGATED,
    POLARITIES,
    DriveOptions,
    OperatorSteps,
    PlacedBody,
    PlannedRun,
    RecordEntry,
    SequenceError,
    record_of_label,
)
from .reader import SCHEMA
from .sequence import Sequence, load_sequence

__all__ = [
    "AS_RECORDED",
    "BOTH",
    "DEFAULT_FRICTION",
    "DEFAULT_PLATE",
    "NEGATED",
    "POLARITIES",
    "SCHEMA",
    "DriveOptions",
    "OperatorSteps",
    "PlacedBody",
    "PlannedRun",
    "RecordEntry",
    "Sequence",
    "SequenceError",
    "load_sequence",
    "record_of_label",
]
