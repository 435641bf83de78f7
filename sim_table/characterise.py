"""The emulator's specimens characterised against the closed forms of rocking: what `rig specimens check` runs.

Each measurement is made in the emulator's own specimen model (:class:`~sim_table.specimens.SpecimenScene`: the
MuJoCo contact, the 1 ms step, the plate driven sample by sample as the emulator drives it), one body alone on the
plate, and set beside its closed form:

- **restitution** e: the body released at rest leaning at half its slenderness (θ0 = α/2) on its +x edge, from
  the amplitude θ2 it reaches on the other edge after the first impact. Between impacts the energy of rocking is
  conserved (``docs/validation.md`` V11: θ'²/2 + p² cos(α − |θ|)), so the angular velocities just before and just
  after the impact are p·√(2(cos(α − θ0) − cos α)) and p·√(2(cos(α − θ2) − cos α)), and e is their ratio — the
  ratio of angular velocities across the impact, read from the two amplitudes (as in a lab, where the peaks are
  what is measured cleanly; the soft contact spreads the impact over a few steps). Closed form: Housner's
  e = 1 − 1.5 sin²α (V4).
- **quarter period**: the time from that release to the first impact (θ = 0, interpolated between steps).
  Closed form (Housner 1963, linearised rocking θ'' = p²(θ − α)): t = arccosh(α/(α − θ0))/p.
- **uplift**: the plate held at the tilt β, its horizontal (surge) acceleration ramped slowly from 0 (by
  :data:`RAMP_G_PER_S`) uphill (the body rocks towards the low side, +x) or downhill (towards the high side); the
  acceleration [g] when |θ'| first exceeds :data:`UPLIFT_RATE`. Closed form: Eq. 1, tan(α − β) and tan(α + β).
- **sliding**: the level plate's acceleration ramped the same way under the body standing with a friction
  coefficient low enough that it slides before it can rock (μ_probe = min(μ, tan α / 2)); the acceleration [g]
  when the body slips against the plate faster than :data:`SLIP_RATE`. Closed form: μ_probe (Coulomb).

Sign conventions as everywhere (``docs/architecture.md``): plate x along the fall line, +x downhill; pitch β > 0
tilts +x down; a body rocking towards +x is going to the low side.

``python -m sim_table.characterise --table5 [--tilt DEG] [--json]`` (what ``rig specimens check`` runs).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace

import numpy as np

from analysis import TABLE_V
from analysis.body import G
from sim_table.scene import Specimen, parse_body
from sim_table.specimens import SpecimenScene

SAMPLE = 1.0e-3
"""Plate update interval [s]: the emulator's controller rate."""

RAMP_G_PER_S = 0.01
"""Slope of the acceleration ramps [g/s]: slow beside the bodies' rocking (p ≈ 5–9 rad/s), so the body follows
the ramp quasi-statically."""

UPLIFT_RATE = 1.0e-3
"""|θ'| [rad/s] that counts as rocking: a body that has started to rock at the ramp's slope passes it within a
few hundredths of a second (≲ 0.001 g later), while the soft contact's creep stays orders of magnitude below."""

SLIP_RATE = 1.0e-3
"""Slip velocity [m/s] of the body against the plate that counts as sliding (as :data:`UPLIFT_RATE`)."""

BATCH = 10
"""Samples per :meth:`~sim_table.specimens.SpecimenScene.advance_many` call."""


@dataclass(frozen=True)
class Characterisation:
    """One body's measurements beside their closed forms (module docstring); accelerations in g, angles in
    degrees, times in seconds."""

    body: str
    b: float
    h: float
    alpha_deg: float
    friction: float
    restitution: float
    restitution_housner: float
    restitution_target: float
    """What the restitution is calibrated to: the body's set restitution, else Housner's."""
    quarter_period_s: float
    quarter_period_closed_form_s: float
    tilt_deg: float
    uplift_g: dict[str, float]
    uplift_eq1_g: dict[str, float]
    sliding_g: float
    sliding_mu: float

    def errors(self) -> dict[str, float]:
        """Relative errors of each measurement against its closed form (signed, fraction)."""
        return {
            "restitution": self.restitution / self.restitution_target - 1.0,
            "quarter_period": self.quarter_period_s / self.quarter_period_closed_form_s - 1.0,
            "uplift_low": self.uplift_g["low"] / self.uplift_eq1_g["low"] - 1.0,
            "uplift_high": self.uplift_g["high"] / self.uplift_eq1_g["high"] - 1.0,
            "sliding": self.sliding_g / self.sliding_mu - 1.0,
        }

    def to_json(self) -> dict[str, object]:
        return {**asdict(self), "errors": self.errors()}


def free_rocking(specimen: Specimen, seconds: float = 3.0) -> tuple[float, float]:
    """(restitution, quarter period [s]) from a release at θ0 = α/2 (module docstring)."""
    alpha = specimen.body.alpha
    lean = 0.5 * alpha
    scene = SpecimenScene([specimen])
    scene.place(leans=[lean])
    n = round(seconds / SAMPLE)
    times = np.arange(1, n + 1) * SAMPLE
    angles = np.empty(n)
    still = np.zeros(6)
    for k in range(n):
        scene.advance(float(times[k]), still, still)
        angles[k] = scene.specimen_angles()[0]
    crossed = np.flatnonzero(angles <= 0.0)
    if crossed.size == 0:
        raise RuntimeError(f"{specimen.body.label()}: released at {lean:.4f} rad it did not rock back in {seconds} s")
    i = int(crossed[0])
    before, after = (lean, 0.0) if i == 0 else (angles[i - 1], times[i - 1])
    quarter = after + (times[i] - after) * before / (before - angles[i])
    window = angles[i:i + round(2.0 / SAMPLE)]
    other = -float(window.min())
    energy = math.cos(alpha - lean) - math.cos(alpha)
    restitution = math.sqrt(max(0.0, math.cos(alpha - other) - math.cos(alpha)) / energy)
    return restitution, quarter


def _ramp(specimen: Specimen, beta: float, direction: float, until: str, limit_g: float) -> float:
    """The plate at pitch ``beta`` [rad], its surge acceleration a(t) = direction · RAMP · t [g]; a [g] when
    ``until`` ("rock": |θ'| > UPLIFT_RATE, "slide": slip velocity > SLIP_RATE; over each batch) first holds."""
    rate = direction * RAMP_G_PER_S * G  # jerk [m/s³]
    scene = SpecimenScene([specimen], plate_pose=[0.0, 0.0, 0.0, 0.0, beta, 0.0])
    settle = 0.2  # s at rest first: the contact settles
    n = round((settle + limit_g / RAMP_G_PER_S) / SAMPLE)
    t = np.arange(1, n + 1) * SAMPLE
    ramp = np.clip(t - settle, 0.0, None)
    poses = np.zeros((n, 6))
    rates = np.zeros((n, 6))
    poses[:, 0], rates[:, 0] = rate * ramp**3 / 6.0, rate * ramp**2 / 2.0
    poses[:, 4] = beta
    last = None  # (θ, place on the plate) at the end of the previous batch
    for k in range(0, n, BATCH):
        part = slice(k, min(k + BATCH, n))
        scene.advance_many(t[part], poses[part], rates[part])
        now = (scene.specimen_angles()[0], scene.specimen_places()[0, 0])
        if last is not None and t[k] >= settle:
            span = BATCH * SAMPLE
            done = (abs(now[0] - last[0]) / span > UPLIFT_RATE if until == "rock"
                    else abs(now[1] - last[1]) / span > SLIP_RATE)
            if done:
                return RAMP_G_PER_S * float(ramp[part.stop - 1])
        last = now
    raise RuntimeError(f"{specimen.body.label()}: did not {until} below {limit_g:g} g")


def characterise(specimen: Specimen, tilt: float) -> Characterisation:
    """Every measurement of the module docstring for ``specimen`` (alone, centred) at the tilt ``tilt`` [rad]."""
    body = specimen.body
    alpha = body.alpha
    if not 0.0 <= tilt < alpha:
        raise ValueError(f"{body.label()}: the tilt {math.degrees(tilt):g}° must be below its α "
                         f"{math.degrees(alpha):.2f}° (it would not stand)")
    alone = replace(specimen, x=0.0, y=0.0)
    restitution, quarter = free_rocking(alone)
    low, high = math.tan(alpha - tilt), math.tan(alpha + tilt)
    uplift = {"low": _ramp(alone, tilt, -1.0, "rock", 1.5 * low + 0.05),
              "high": _ramp(alone, tilt, +1.0, "rock", 1.5 * high + 0.05)}
    mu = min(specimen.friction, 0.5 * math.tan(alpha))
    sliding = _ramp(replace(alone, friction=mu), 0.0, +1.0, "slide",
                    1.5 * mu + 0.05)
    return Characterisation(
        body=body.label(), b=body.b, h=body.h, alpha_deg=math.degrees(alpha), friction=specimen.friction,
        restitution=restitution, restitution_housner=alone.housner_restitution,
        restitution_target=alone.housner_restitution if specimen.restitution is None else specimen.restitution,
        quarter_period_s=quarter, quarter_period_closed_form_s=math.acosh(alpha / (alpha - 0.5 * alpha)) / body.p,
        tilt_deg=math.degrees(tilt), uplift_g=uplift, uplift_eq1_g={"low": low, "high": high},
        sliding_g=sliding, sliding_mu=mu)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m sim_table.characterise",
                                description="Characterise the emulator's specimens against the closed forms.")
    p.add_argument("--body", action="append", default=[], metavar="BxH[;mu=F][;restitution=E]",
                   help="a body b×h [m], optionally its friction coefficient (else --friction) and measured "
                        "restitution (the target of its impacts; else Housner's); the emulator's --body syntax")
    p.add_argument("--table5", action="store_true", help="the paper's seven Table V bodies")
    p.add_argument("--tilt", type=float, default=5.0, help="plate tilt for the uplift [deg] (default 5)")
    p.add_argument("--friction", type=float, default=0.8, help="friction coefficient μ (default 0.8)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    args = p.parse_args(argv)
    try:
        specimens = [parse_body(text if ";mu=" in text else f"{text};mu={args.friction!r}") for text in args.body]
    except ValueError as exc:
        p.error(str(exc))
    specimens += [Specimen(body, friction=args.friction) for body in (TABLE_V if args.table5 else [])]
    if not specimens:
        p.error("give --body BxH or --table5")
    try:
        results = [characterise(s, math.radians(args.tilt)) for s in specimens]
    except (ValueError, RuntimeError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps({"bodies": [r.to_json() for r in results]}))
        return 0
    for r in results:
        e = r.errors()
        target = (f"Housner {r.restitution_housner:.3f}" if r.restitution_target == r.restitution_housner
                  else f"set {r.restitution_target:.3f}, Housner {r.restitution_housner:.3f}")
        print(f"{r.body}: restitution {r.restitution:.3f} ({target}, {100 * e['restitution']:+.1f} %); "
              f"quarter period {r.quarter_period_s:.4f} s (closed form "
              f"{r.quarter_period_closed_form_s:.4f} s, {100 * e['quarter_period']:+.1f} %); uplift at "
              f"{r.tilt_deg:g}° {r.uplift_g['low']:.4f} g low / {r.uplift_g['high']:.4f} g high (Eq. 1 "
              f"{r.uplift_eq1_g['low']:.4f} / {r.uplift_eq1_g['high']:.4f}, {100 * e['uplift_low']:+.1f} / "
              f"{100 * e['uplift_high']:+.1f} %); sliding {r.sliding_g:.4f} g at μ {r.sliding_mu:.3f} "
              f"({100 * e['sliding']:+.1f} %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
