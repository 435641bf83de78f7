"""The specimens of a test and the MuJoCo model of them standing on the plate.

Frames and units (docs/architecture.md §2, ``analysis.table.model``): SI, z up. The model's world frame is the
platform frame at its home pose (the base frame shifted up by ``home_height``; gravity is uniform, so the
shift changes nothing). The plate body's origin is the centre of the plate's top surface, and its six
joints reproduce the pose convention exactly: slides along world x, y, z (surge, sway, heave [m]), then
hinges about z, y', x'' (yaw, pitch, roll [rad]); MuJoCo composes a body's joints in order in the local
frame, so the plate's orientation is ``Rz(yaw) Ry(pitch) Rx(roll)`` and the joint velocities are the pose
rates. :data:`PLATE_QPOS_ORDER` maps pose columns to the plate's ``qpos``/``qvel`` slots (it is its own
inverse).

How the plate is driven, and why. A **mocap** plate does not work: MuJoCo gives a mocap body no velocity
in the contact solver, so a plate moved through ``mocap_pos`` slides out from under the bodies instead of
dragging them (checked: a plate accelerating at 2 m/s² for 1 s left a block with μ = 0.8 exactly where it
stood). A **weld to a mocap body** or stiff **position actuators** would make the plate a soft spring that
lags by an amount depending on the bodies' loads. Setting the joints' ``qpos``/``qvel`` alone each step
shows the bodies a velocity jump that the contact's damping corrects softly, a step late. Here every plate
joint carries an armature of :data:`PLATE_ARMATURE` (a huge inertia; the plate's own mass is small and
gravity-compensated), and the scene prescribes the joints' positions and velocities before each step and
their acceleration as the generalised force armature × acceleration (:mod:`sim_table.specimens`): the
bodies' reactions change the plate's motion by nothing measurable, and the plate's acceleration reaches a
body through the contact constraint within the same step, so friction drags the bodies and a tilting plate
tilts them.

Specimens are free boxes of the body's ``b`` (along plate x), depth (along y) and ``h``, standing on the plate's
top surface; a body whose centre of mass is off its centroid (``Body.b_cg``, ``h_cg``: from the base's −x
corner, and above the base) carries it there, with the uniform box's moment of inertia about it (the analysis's
assumption, ``analysis.body``), through an explicit ``<inertial>`` (a centred body keeps the box geom's own).
Their contacts with the plate take the specimen's friction μ and damping ratio (geom ``priority``: the
specimen's parameters win over the plate's), condim 3: Coulomb sliding friction only, as in the paper's models
(a box resting on an edge or a face already gets several contact points).
:class:`ContactSettings` holds the time step and the contact model.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco

from analysis.body import Body, G
from analysis.errors import AnalysisInputError

PLATE_THICKNESS = 0.1
"""Thickness of the plate box [m] (its top surface is the plate frame's z = 0)."""

PLATE_MASS = 1.0
"""Mass of the plate body [kg]: small beside :data:`PLATE_ARMATURE`, and gravity-compensated."""

PLATE_ARMATURE = 1.0e9
"""Armature of each plate joint [kg or kg·m²]: bodies' reactions (≲ 10³ N) change the plate's acceleration
by ≲ 1e-6 m/s² within a step, and the prescribed state is restored before the next."""

PLATE_QPOS_ORDER = (0, 1, 2, 5, 4, 3)
"""Pose column of each plate qpos slot: qpos is (surge, sway, heave, yaw, pitch, roll)."""

PLATE_MARGIN = 0.1
"""Plate beyond the farthest point a fallen specimen can reach [m]."""

DEFAULT_DENSITY = 600.0
"""Density of a specimen whose mass is not given [kg/m³]: agglomerated wood, as Table V's bodies."""

MIN_CONTACT_RESTITUTION = 0.1
"""Lowest contact restitution (Housner's; b/h ≤ 1.22) that the impact model scales to a set restitution: the
factor restitution / contact restitution would otherwise amplify what little rocking a stocky body's contact
leaves."""


class SpecimenError(ValueError):
    """A specimen, a scene or a plate motion the emulator cannot run: the message says which and why."""


@dataclass(frozen=True)
class ContactSettings:
    """Physics step and contact model (tuned on VALIDATION.md V2; see the tests).

    ``timestep`` [s]: MuJoCo's step (semi-implicit Euler). ``time_constant`` [s]: the contact's ``solref``
    time constant, with the specimen's damping ratio as the second number: stiff (four steps, MuJoCo's
    rule asks ≥ 2) so that a resting body sinks < 1 µm and a pivoting corner stays put. ``solimp``: the
    contact is nearly hard from zero penetration (impedance 0.99 → 0.999 over 1 mm). Friction uses the
    elliptic cone (isotropic Coulomb friction) with impratio 1, solved by Newton; MuJoCo's no-slip
    post-solver is **off**: with the jointed plate it made resting bodies hop (µm to mm), while without it
    a body on a 7° plate creeps < 0.1 mm in 5 s.
    """

    timestep: float = 1.0e-3
    time_constant: float = 4.0e-3
    solimp: tuple[float, float, float] = (0.99, 0.999, 1.0e-3)
    tolerance: float = 1.0e-12
    """Newton's convergence tolerance (MuJoCo's default is 1e-8). The plate's armature (1e9) dominates the
    solver's cost, so at 1e-8 it stopped after one iteration with the light bodies' contacts unresolved: Table V's
    0.36 kg and 0.56 kg bodies chattered on a 5° plate at rest (|θ| up to 0.03 rad, creeping mm downhill) and a
    body released at rest on an edge could stay frozen. At 1e-12 they stand still (|θ| < 1e-5) and the step
    costs the same (`rig specimens check`, tests/emulator/test_specimens.py)."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.timestep) and 0 < self.timestep <= 0.01):
            raise SpecimenError(f"ContactSettings: timestep must be in (0, 0.01] s, got {self.timestep!r}")
        if not self.time_constant >= 2 * self.timestep:
            raise SpecimenError(
                f"ContactSettings: time_constant {self.time_constant!r} s must be at least twice the timestep "
                f"{self.timestep!r} s (MuJoCo's stability rule for solref)"
            )
        dmin, dmax, width = self.solimp
        if not (0 < dmin <= dmax < 1 and width > 0):
            raise SpecimenError(f"ContactSettings: solimp needs 0 < dmin <= dmax < 1, width > 0, got {self.solimp!r}")


@dataclass(frozen=True)
class Specimen:
    """One body of the test at its place on the plate.

    ``x``, ``y`` [m]: centre of its base in the plate frame (x along the fall line, +x downhill); the
    body's ``b`` lies along x, its depth along y (default 2·b, the paper's minimum). Its mass defaults to
    :data:`DEFAULT_DENSITY` × volume. ``friction``: the coefficient μ between body and plate [-];
    ``damping_ratio`` [-] of its contacts: 1 = no bounce (near-plastic impacts, as the paper assumes),
    below 1 the contact bounces (a restitution-like softness). ``restitution`` [-], in (0, 1]: the body's
    measured coefficient of restitution (ratio of angular velocities across a rocking impact), which its impacts
    then reproduce (:mod:`sim_table.specimens`, the impact model); None: the contact's own, Housner's
    1 − 1.5 sin²α within a few per cent (``docs/specimens.md``).
    """

    body: Body
    x: float = 0.0
    y: float = 0.0
    friction: float = 0.8
    damping_ratio: float = 1.0
    restitution: float | None = None

    def __post_init__(self) -> None:
        name = self.body.label()
        if not (math.isfinite(self.x) and math.isfinite(self.y)):
            raise SpecimenError(f"specimen {name}: its place must be finite, got ({self.x!r}, {self.y!r}) m")
        if not (math.isfinite(self.friction) and self.friction > 0):
            raise SpecimenError(f"specimen {name}: friction μ must be > 0, got {self.friction!r}")
        if not 0 < self.damping_ratio <= 1:
            raise SpecimenError(f"specimen {name}: damping ratio must be in (0, 1], got {self.damping_ratio!r}")
        if self.restitution is not None and not (math.isfinite(self.restitution) and 0 < self.restitution <= 1):
            raise SpecimenError(f"specimen {name}: restitution must be in (0, 1], got {self.restitution!r}")
        if self.restitution is not None and self.housner_restitution < MIN_CONTACT_RESTITUTION:
            raise SpecimenError(
                f"specimen {name}: a restitution can be set only for a body whose contact restitution (Housner's "
                f"1 - 1.5 sin²α = {self.housner_restitution:.3f}) is at least {MIN_CONTACT_RESTITUTION:g}: "
                f"b/h = {self.body.b / self.body.h:.3f} is too stocky for the impact model (docs/specimens.md)")

    @property
    def housner_restitution(self) -> float:
        """Housner's coefficient of restitution 1 − 1.5 sin²α of the body [-] (what its contact dissipates), the
        lower of the two directions' (:attr:`housner_restitutions`) for a body whose centre of mass is off the
        middle."""
        if self.body.centred:
            return 1.0 - 1.5 * math.sin(self.body.alpha) ** 2
        return min(self.body.housner_restitutions())

    @property
    def housner_restitutions(self) -> tuple[float, float]:
        """Housner's ratio per impact direction [-]: at an impact ending rocking on the +x corner, and on the −x
        corner (``Body.housner_restitutions``; 1 − 1.5 sin²α both ways for a centred body)."""
        if self.body.centred:
            return self.housner_restitution, self.housner_restitution
        return self.body.housner_restitutions()

    @property
    def depth(self) -> float:
        """Extent along the plate's y [m]."""
        return self.body.depth if self.body.depth is not None else 2.0 * self.body.b

    @property
    def mass(self) -> float:
        """Mass [kg]."""
        if self.body.mass is not None:
            return self.body.mass
        return DEFAULT_DENSITY * self.body.b * self.body.h * self.depth

    def footprint(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of its base on the plate [m]."""
        hb, hd = 0.5 * self.body.b, 0.5 * self.depth
        return self.x - hb, self.x + hb, self.y - hd, self.y + hd


def parse_body(text: str) -> Specimen:
    """``BxH[@X,Y][;depth=D][;mass=M][;mu=F][;restitution=E][;cg=BCG,HCG]`` (the emulator's ``--body``): a block
    b × h [m] whose base centre stands at plate (x, y) [m] (default the centre), optionally its depth [m], mass [kg],
    friction coefficient μ, measured restitution e (:class:`Specimen`'s defaults) and centre of gravity (b_cg from
    the base's −x corner, h_cg above the base [m]; default the middle); :class:`SpecimenError` names what is
    wrong."""
    head, *options = text.split(";")
    size, _, place = head.partition("@")
    body = Body.parse(size)
    try:
        x, y = (float(v) for v in place.split(",")) if place else (0.0, 0.0)
        pairs = [(name.strip(), value) for name, _, value in (o.partition("=") for o in options)]
        cg = [tuple(float(v) for v in value.split(",")) for name, value in pairs if name == "cg"]
        extra = {name: float(value) for name, value in pairs if name != "cg"}
        if any(len(c) != 2 for c in cg):
            raise ValueError
    except ValueError:
        raise SpecimenError(f"--body {text!r}: expected BxH@X,Y[;depth=D][;mass=M][;mu=F][;restitution=E]"
                            "[;cg=BCG,HCG] in metres and kg, e.g. 0.05x0.50@0.3,0;depth=0.1;mass=5;cg=0.026,0.24"
                            ) from None
    unknown = set(extra) - {"depth", "mass", "mu", "restitution"}
    if unknown:
        raise SpecimenError(f"--body {text!r}: unknown option(s) {', '.join(sorted(unknown))} "
                            "(depth, mass, mu, restitution, cg)")
    if "depth" in extra or "mass" in extra or cg:
        b_cg, h_cg = cg[-1] if cg else (None, None)
        try:
            body = Body(body.b, body.h, depth=extra.get("depth"), mass=extra.get("mass"), name=body.name, b_cg=b_cg,
                        h_cg=h_cg)
        except AnalysisInputError as exc:
            raise SpecimenError(f"--body {text!r}: {exc}") from None
    friction = {"friction": extra["mu"]} if "mu" in extra else {}
    return Specimen(body, x=x, y=y, restitution=extra.get("restitution"), **friction)


def plate_half_size(specimens: Sequence[Specimen]) -> tuple[float, float]:
    """Half-extents (x, y) of a plate on which every specimen, fallen any way, still lies [m]."""
    half_x = max(abs(s.x) + 0.5 * s.body.b + s.body.h for s in specimens)
    half_y = max(abs(s.y) + 0.5 * s.depth + s.body.h for s in specimens)
    return half_x + PLATE_MARGIN, half_y + PLATE_MARGIN


def check_placements(specimens: Sequence[Specimen]) -> None:
    """Raise :class:`SpecimenError` when there is no specimen or two bases overlap."""
    if not specimens:
        raise SpecimenError("a scene needs at least one specimen")
    boxes = [s.footprint() for s in specimens]
    for i, (x0, x1, y0, y1) in enumerate(boxes):
        for j in range(i):
            a0, a1, b0, b1 = boxes[j]
            if x0 < a1 and a0 < x1 and y0 < b1 and b0 < y1:
                raise SpecimenError(
                    f"specimens {j} ({specimens[j].body.label()}) and {i} ({specimens[i].body.label()}) overlap "
                    "on the plate"
                )


def _plate_joints() -> str:
    joints = (
        ("surge", "slide", "1 0 0"), ("sway", "slide", "0 1 0"), ("heave", "slide", "0 0 1"),
        ("yaw", "hinge", "0 0 1"), ("pitch", "hinge", "0 1 0"), ("roll", "hinge", "1 0 0"),
    )
    return "\n".join(
        f'      <joint name="{name}" type="{kind}" axis="{axis}" armature="{PLATE_ARMATURE!r}"/>'
        for name, kind, axis in joints
    )


def _specimen_body(i: int, s: Specimen, contact: ContactSettings) -> str:
    hb, hd, hh = 0.5 * s.body.b, 0.5 * s.depth, 0.5 * s.body.h
    solimp = " ".join(repr(v) for v in contact.solimp)
    inertial = ""
    if not s.body.centred:  # the centre of mass off the box's centre, the uniform box's inertia about it
        b_cg, h_cg = s.body.cg
        m, (b, d, h) = s.mass, (s.body.b, s.depth, s.body.h)
        diag = (m * (d * d + h * h) / 12.0, m * (b * b + h * h) / 12.0, m * (b * b + d * d) / 12.0)
        inertial = (f'      <inertial pos="{b_cg - hb!r} 0 {h_cg - hh!r}" mass="{m!r}" '
                    f'diaginertia="{" ".join(repr(v) for v in diag)}"/>\n')
    return (
        f'    <body name="specimen{i}" pos="{s.x!r} {s.y!r} {hh!r}">\n'
        f"{inertial}"
        f"      <freejoint/>\n"
        f'      <geom type="box" size="{hb!r} {hd!r} {hh!r}" mass="{s.mass!r}" priority="1" condim="3"\n'
        f'            friction="{s.friction!r} 0 0" solref="{contact.time_constant!r} {s.damping_ratio!r}"'
        f' solimp="{solimp}"/>\n'
        f"    </body>"
    )


def scene_xml(specimens: Sequence[Specimen], contact: ContactSettings) -> str:
    """MJCF of the plate (sized by :func:`plate_half_size`) and the specimens upright on the level plate."""
    half_x, half_y = plate_half_size(specimens)
    half_t = 0.5 * PLATE_THICKNESS
    bodies = "\n".join(_specimen_body(i, s, contact) for i, s in enumerate(specimens))
    return f"""<mujoco model="specimens">
  <option timestep="{contact.timestep!r}" gravity="0 0 {-G!r}" cone="elliptic" solver="Newton"
          tolerance="{contact.tolerance!r}"/>
  <worldbody>
    <body name="plate" gravcomp="1">
{_plate_joints()}
      <geom type="box" size="{half_x!r} {half_y!r} {half_t!r}" pos="0 0 {-half_t!r}" mass="{PLATE_MASS!r}"/>
    </body>
{bodies}
  </worldbody>
</mujoco>
"""


def build_model(specimens: Sequence[Specimen], contact: ContactSettings) -> mujoco.MjModel:
    """Check the placements and compile the scene."""
    check_placements(specimens)
    return mujoco.MjModel.from_xml_string(scene_xml(specimens, contact))
