"""Sequence files (TOML): what a session on the table runs (docs/architecture.md §4; the file: docs/sequence-files.md).

A sequence names the table connection, the rig configuration, the bodies and their places on the plate,
the plate angles, the records with their scale policy, the repetitions and the operator's steps. It is
checked before anything moves: `load_sequence` checks types, keys, ranges and placements; `Sequence.check`
resolves every record, checks that every body can stand at every angle (β < α) and prepares every drive
against the table model. Every error is a `SequenceError` ``FILE:LINE: key.path: what is wrong, expected …``
(list items counted from 1: ``bodies[2].h``, ``records[3].scale``; a missing top-level key at line 1).

Units are SI unless the key says otherwise: lengths in metres, mass in kg, ``_deg`` degrees, ``_s``
seconds, ``_hz`` Hz; body places in the plate frame, +x downhill. The keys, their ranges, the scale policy,
windows and ``records_from``: docs/sequence-files.md §Layout; the checks: §Checks and errors; in Python
(``load_sequence``, ``Sequence.check``, ``plan``, ``prepare``): §Python.
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
