"""The parts of a sequence: placed bodies, record entries, operator steps, drive options, planned runs.

Units: lengths in metres, mass in kg, angles in degrees where the name says ``_deg`` (as in the file) and
radians otherwise, times in seconds, frequencies in Hz. Every part has a ``to_dict`` in the sequence file's
own layout (plain JSON types), so that a sequence's ``to_dict`` reads back with ``Sequence.from_dict``.
"""

from __future__ import annotations

import math
import re
import string
from dataclasses import dataclass
from typing import Any

from analysis.body import Body
from rig.drive.prepare import SETTLE_SECONDS


class SequenceError(ValueError):
    """A sequence that cannot be run: ``FILE:LINE: key.path: what is wrong, expected …``.

    ``source`` is the file (or ``<dict>``), ``line`` the 1-based line of the key (None when unknown),
    ``key`` the dotted key path (list items counted from 1, e.g. ``bodies[2].h``; empty for the whole file)
    and ``problem`` the message without the place.
    """

    def __init__(self, source: str, line: int | None, key: str, problem: str) -> None:
        where = f"{source}:{line}" if line else source
        super().__init__(f"{where}: {key}: {problem}" if key else f"{where}: {problem}")
        self.source, self.line, self.key, self.problem = source, line, key, problem


DEFAULT_FRICTION = 0.8
"""Friction coefficient μ between a body and the plate when the file gives none [-] (the emulator's)."""

DEFAULT_PLATE = (3.0, 3.0)
"""Usable top surface of the plate along x (fall line) and y [m]: the rig's ~3 m plate."""

DEFAULT_PROMPT = "Place the bodies at their marks on the plate ({angle_deg:g}°), then confirm."
"""The operator's prompt before each angle; ``{angle_deg}``, ``{bodies}`` and ``{sequence}`` are filled in."""

PROMPT_FIELDS = ("angle_deg", "bodies", "sequence")
"""The placeholders a ``place_bodies`` prompt may use."""

MAX_PROMPT_CHARS = 500
"""Longest ``place_bodies`` prompt as written [characters]."""

MAX_FIELD_WIDTH = 80
"""Largest width and precision of a placeholder's format spec (``{angle_deg:>8.2f}``) [characters]."""

#: A simple format spec: fill and align, sign, ``#``, ``0``, width, grouping, precision, type; no nested fields.
_SPEC_RE = re.compile(
    r"(?:[^{}]?[<>^=])?[-+ ]?#?0?(?P<width>\d{1,3})?[,_]?(?:\.(?P<precision>\d{1,3}))?[bcdeEfFgGnosxX%]?"
)

_SAMPLE = {"angle_deg": 4.5, "bodies": "1: T5-1 at (0, 0) m", "sequence": "quick"}


def _prompt_parts(template: str) -> list[tuple[str, str | None, str]]:
    """(literal text, field, format spec) of a prompt; ValueError saying what is wrong with it.

    A restricted formatter: a field is one of `PROMPT_FIELDS` by its plain name (no attribute or index
    access such as ``{bodies.__class__}`` or ``{bodies[0]}``, no conversion ``!r``), its spec a simple one of
    bounded width (`MAX_FIELD_WIDTH`); user text is never handed to ``str.format``.
    """
    if len(template) > MAX_PROMPT_CHARS:
        raise ValueError(f"the prompt is {len(template):,} characters; expected at most {MAX_PROMPT_CHARS}")
    try:
        parsed = list(string.Formatter().parse(template))
    except ValueError as exc:
        raise ValueError(f"{exc} (write {{{{ and }}}} for a literal brace)") from None
    parts: list[tuple[str, str | None, str]] = []
    fields = ", ".join("{" + f + "}" for f in PROMPT_FIELDS)
    for literal, field, spec, conversion in parsed:
        if field is not None and field not in PROMPT_FIELDS:
            raise ValueError(f"placeholder {{{field}}} is not one of {fields} (plain names only: no attributes, "
                             "indices or positions)")
        if conversion is not None:
            raise ValueError(f"placeholder {{{field}!{conversion}}}: conversions are not allowed; expected {fields}")
        spec = spec or ""
        found = _SPEC_RE.fullmatch(spec)
        if found is None:
            raise ValueError(f"placeholder {{{field}:{spec}}}: expected a simple format spec such as :g, :.1f or :>8")
        for part in ("width", "precision"):
            if found[part] is not None and int(found[part]) > MAX_FIELD_WIDTH:
                raise ValueError(f"placeholder {{{field}:{spec}}}: {part} {int(found[part])} is over "
                                 f"{MAX_FIELD_WIDTH} characters")
        if field is not None:
            try:
                format(_SAMPLE[field], spec)
            except ValueError as exc:
                raise ValueError(f"placeholder {{{field}:{spec}}}: {exc}") from None
        parts.append((literal, field, spec))
    return parts


def check_prompt(template: str) -> None:
    """Raise ValueError saying what is wrong with a ``place_bodies`` prompt (see `_prompt_parts`)."""
    _prompt_parts(template)


def format_prompt(template: str, values: dict[str, Any]) -> str:
    """The prompt with its placeholders filled from ``values`` (keys `PROMPT_FIELDS`), restricted as
    `_prompt_parts` says."""
    return "".join(literal + ("" if field is None else format(values[field], spec))
                   for literal, field, spec in _prompt_parts(template))


@dataclass(frozen=True)
class PlacedBody:
    """One body at its place on the plate.

    ``body_id`` is its 1-based position in the file (stable: the session file's ``body_id``); ``body`` its
    dimensions b (along the fall line), h, depth [m], mass [kg] and centre of gravity (``Body.b_cg``, from the
    base's −x corner, and ``Body.h_cg``; None: the middle); ``x``, ``y`` [m] the centre of its base
    in the plate frame (x along the fall line, +x downhill); ``friction`` μ [-] between body and plate;
    ``restitution`` [-]: its coefficient of restitution as measured in the lab (ratio of angular velocities
    across a rocking impact), which the emulated specimen's impacts reproduce, or None (the emulator's contact:
    Housner's 1 − 1.5 sin²α).
    """

    body_id: int
    body: Body
    x: float
    y: float
    friction: float = DEFAULT_FRICTION
    restitution: float | None = None

    @property
    def name(self) -> str:
        """The body's name (from the file, Table V's ``T5-N``, or ``body N``)."""
        return self.body.name

    @property
    def depth(self) -> float:
        """Extent along the plate's y [m]."""
        return float(self.body.depth) if self.body.depth is not None else 2.0 * self.body.b

    def footprint(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of its base on the plate [m]."""
        hb, hd = 0.5 * self.body.b, 0.5 * self.depth
        return self.x - hb, self.x + hb, self.y - hd, self.y + hd

    def standing_problem(self, angle_deg: float) -> str | None:
        """Why the body cannot stand still on a plate tilted by ``angle_deg`` [deg], or None if it can.

        A block tips over downhill once β ≥ α₊, its slenderness towards +x (atan(b/h) for a centred block,
        atan((b − b_cg)/h_cg) in general), and slides once tan β ≥ μ.
        """
        beta = math.radians(angle_deg)
        alpha = math.degrees(self.body.alpha_plus)
        what = f"body {self.body_id} ({self.name}, b = {self.body.b:g} m, h = {self.body.h:g} m)"
        formula = "atan(b/h)" if self.body.centred else "atan((b − b_cg)/h_cg), towards +x (downhill),"
        if beta >= self.body.alpha_plus:
            return (f"{what} cannot stand at β = {angle_deg:g}°: its slenderness angle α = {formula} = "
                    f"{alpha:.2f}°, and a block tips over once β ≥ α (expected β < {alpha:.2f}°)")
        if math.tan(beta) >= self.friction:
            return (f"{what} would slide at β = {angle_deg:g}°: tan β = {math.tan(beta):.3f} ≥ friction μ = "
                    f"{self.friction:g} (expected tan β < μ)")
        return None

    def to_dict(self) -> dict[str, Any]:
        b = self.body
        return {"body_id": self.body_id, "name": b.name, "b": b.b, "h": b.h, "depth": self.depth,
                "mass": b.mass, "x": self.x, "y": self.y, "friction": self.friction,
                **({} if b.b_cg is None else {"b_cg": b.b_cg}), **({} if b.h_cg is None else {"h_cg": b.h_cg}),
                **({} if self.restitution is None else {"restitution": self.restitution})}


AS_RECORDED = "as recorded"
NEGATED = "negated"
BOTH = "both"
POLARITIES = (AS_RECORDED, NEGATED, BOTH)
"""A sequence's ``polarity`` values: the record as recorded, negated, or both (each record played twice)."""

NEGATED_LABEL = " (negated)"
"""What a negated record's label (the session's run ``record``) ends with."""


def record_of_label(label: str) -> tuple[str, int]:
    """(the record's label without its polarity, polarity +1 or −1) from a run's ``record`` label."""
    if label.endswith(NEGATED_LABEL):
        return label.removesuffix(NEGATED_LABEL), -1
    return label, 1


@dataclass(frozen=True)
class RecordEntry:
    """One record of the sequence and how to play it.

    ``spec`` is the record as written (``SUITE:NAME``, ``library:NAME``, a file or ``H1+H2[+UP]``),
    ``resolved`` the same with file paths made absolute (relative paths are read from the sequence file's
    folder). ``scale`` is None for the ``"table"`` policy (the largest factor ≤ 1 inside the table's limits)
    or a fixed factor in (0, 1]. ``window`` (t0, t1) [s] plays only that part of the record (the drive
    preparation tapers its ends and brings the table to rest). ``corner`` [Hz] fixes the high-pass corner
    (None: the ``[drive]`` option, else automatic). ``dt`` [s] and ``units`` are for record files that do not
    state them. ``key``/``line`` say where the entry is in the file (``records[2]``, ``records_from``).
    ``polarity``: +1 plays the record as recorded, −1 negated — its fall-line component (``acc_h``, surge) times
    −1, the second horizontal and the vertical component as recorded: the mirror image of the motion across the
    plane normal to the fall line, which the paper's analysis plays beside every record (``polarity = "both"``).
    """

    spec: str
    resolved: str
    scale: float | None = None
    window: tuple[float, float] | None = None
    corner: float | None = None
    dt: float | None = None
    units: str | None = None
    key: str = "records"
    line: int | None = None
    drive: str | None = None
    """A drive file to play instead of preparing the record (``rig iterate``'s compensated drive), absolute path."""
    polarity: int = 1

    @property
    def scale_policy(self) -> str | float:
        """``"table"`` or the fixed factor."""
        return "table" if self.scale is None else self.scale

    def label(self) -> str:
        """The spec with its window and polarity, e.g. ``fema:KOBE/NIS000 [5-10 s] (negated)`` (the session's run
        ``record``; `record_of_label` splits it again)."""
        label = self.spec if self.window is None else f"{self.spec} [{self.window[0]:g}-{self.window[1]:g} s]"
        return label + (NEGATED_LABEL if self.polarity < 0 else "")

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"record": self.resolved, "scale": self.scale_policy,
                               "polarity": NEGATED if self.polarity < 0 else AS_RECORDED}
        for key, value in (("window_s", self.window), ("corner_hz", self.corner), ("dt_s", self.dt),
                           ("units", self.units), ("drive", self.drive)):
            if value is not None:
                out[key] = list(value) if isinstance(value, tuple) else value
        return out


@dataclass(frozen=True)
class OperatorSteps:
    """What the orchestrator asks of the operator.

    ``place_bodies``: the prompt shown before each angle (placeholders ``{angle_deg}``, ``{bodies}``,
    ``{sequence}``); ``confirm_before_run``: wait for a confirmation before each run moves the table;
    ``ask_detections``: ask the operator which bodies overturned and which way after each run (instead of
    relying on the sensors alone).
    """

    place_bodies: str = DEFAULT_PROMPT
    confirm_before_run: bool = True
    ask_detections: bool = False

    def place_prompt(self, angle_deg: float, bodies: tuple[PlacedBody, ...] = (), sequence: str = "") -> str:
        """The placement prompt for one angle [deg]."""
        names = ", ".join(f"{b.body_id}: {b.name} at ({b.x:g}, {b.y:g}) m" for b in bodies)
        return format_prompt(self.place_bodies, {"angle_deg": angle_deg, "bodies": names, "sequence": sequence})

    def to_dict(self) -> dict[str, Any]:
        return {"place_bodies": self.place_bodies, "confirm_before_run": self.confirm_before_run,
                "ask_detections": self.ask_detections}


@dataclass(frozen=True)
class DriveOptions:
    """Drive preparation options for every record: ``settle`` [s] held at the tilt before and after the
    motion, ``corner`` [Hz] a fixed high-pass corner (None: automatic, as ``rig prepare``), ``headroom`` the margin
    the scale factor leaves on every limit (a share; ``headroom_pct`` in the file, ``rig prepare --headroom``)."""

    settle: float = SETTLE_SECONDS
    corner: float | None = None
    headroom: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"settle_s": self.settle}
        if self.headroom:
            out["headroom_pct"] = 100.0 * self.headroom
        if self.corner is not None:
            out["corner_hz"] = self.corner
        return out


@dataclass(frozen=True)
class PlannedRun:
    """One run of the plan: a record at an angle, one repetition.

    ``plan_index`` 0…n−1 in the order the runs are played (per angle in file order, per record, per
    repetition); ``angle_index`` and ``record_index`` index ``Sequence.angles_deg`` and ``Sequence.records``;
    ``repetition`` counts from 0.
    """

    plan_index: int
    angle_index: int
    angle_deg: float
    record_index: int
    record: RecordEntry
    repetition: int

    @property
    def angle(self) -> float:
        """The plate tilt β [rad]."""
        return math.radians(self.angle_deg)

    def to_dict(self) -> dict[str, Any]:
        return {"plan_index": self.plan_index, "angle_index": self.angle_index, "angle_deg": self.angle_deg,
                "record_index": self.record_index, "record": self.record.resolved,
                "polarity": self.record.polarity, "scale": self.record.scale_policy, "repetition": self.repetition}
