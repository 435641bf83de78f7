"""The emulator's specimens characterised against the closed forms of rocking: what `rig specimens check` runs.

Each measurement is made in the emulator's own specimen model (:class:`~sim_table.specimens.SpecimenScene`: the
MuJoCo contact, the 1 ms step, the plate driven sample by sample as the emulator drives it), one body alone on the
plate, and set beside its closed form:

Each side is measured: a body whose centre of mass is off its centroid (``Body.b_cg``, ``h_cg``) has a slenderness
α±, a distance R± from each corner to its centre of mass and p±² = g R±/(i_g² + R±²) per corner (``analysis.body``;
α+ = α− = α, p+ = p− = p for a centred body).

- **restitution** e±: the body released at rest leaning at half its slenderness (θ0 = α±/2) on its ±x edge, from
  the amplitude θ2 it reaches on the other edge after the first impact. Between impacts the energy of rocking is
  conserved (``docs/validation.md`` V11: θ'²/2 + p² cos(α − |θ|) on each corner), so the angular velocities just
  before and just after the impact are p±·√(2(cos(α± − θ0) − cos α±)) and p∓·√(2(cos(α∓ − θ2) − cos α∓)), and e±
  is their ratio — the ratio of angular velocities across the impact that ends rocking on the ± corner, read from
  the two amplitudes (as in a lab, where the peaks are what is measured cleanly; the soft contact spreads the
  impact over a few steps). Closed form: Housner's, 1 − 1.5 sin²α (V4) for a centred body, per direction
  (``Body.housner_restitutions``, V14) for one whose centre of mass is off the middle.
- **quarter period** on each side: the time from that release to the first impact (θ = 0, interpolated between
  steps). Closed form (Housner 1963, linearised rocking θ'' = p²(θ − α)): t = arccosh(α±/(α± − θ0))/p±.
- **uplift**: the plate held at the tilt β, its horizontal (surge) acceleration ramped slowly from 0 (by
  :data:`RAMP_G_PER_S`) uphill (the body rocks towards the low side, +x) or downhill (towards the high side); the
  acceleration [g] when |θ'| first exceeds :data:`UPLIFT_RATE`. Closed form: Eq. 1, tan(α+ − β) and tan(α− + β).
  The **slenderness** each side shows, atan(low) + β and atan(high) − β, is set beside the body's α+ and α−.
- **sliding**: the level plate's acceleration ramped the same way under the body standing with a friction
  coefficient low enough that it slides before it can rock (μ_probe = min(μ, tan α / 2), α the smaller of α±);
  the acceleration [g] when the body slips against the plate faster than :data:`SLIP_RATE`. Closed form: μ_probe
  (Coulomb).

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
    degrees, times in seconds. ``restitution*`` and ``quarter_period*`` without a suffix are the +x side's
    (released on its +x edge), ``*_minus`` the −x side's; ``b_cg``, ``h_cg`` [m] the centre of mass (the middle
    unless the body gives it), ``alpha_deg`` the box's atan(b/h), ``slenderness_deg`` the body's α+, α− and
    ``slenderness_measured_deg`` what the uplift on each side shows."""

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
    b_cg: float = math.nan
    h_cg: float = math.nan
    slenderness_deg: dict[str, float] | None = None
    slenderness_measured_deg: dict[str, float] | None = None
    restitution_minus: float = math.nan
    restitution_housner_minus: float = math.nan
    restitution_target_minus: float = math.nan
    quarter_period_minus_s: float = math.nan
    quarter_period_closed_form_minus_s: float = math.nan

    def errors(self) -> dict[str, float]:
        """Relative errors of each measurement against its closed form (signed, fraction); the slenderness as the
        difference in degrees (measured − the body's)."""
        out = {
            "restitution": self.restitution / self.restitution_target - 1.0,
            "quarter_period": self.quarter_period_s / self.quarter_period_closed_form_s - 1.0,
            "uplift_low": self.uplift_g["low"] / self.uplift_eq1_g["low"] - 1.0,
            "uplift_high": self.uplift_g["high"] / self.uplift_eq1_g["high"] - 1.0,
            "sliding": self.sliding_g / self.sliding_mu - 1.0,
        }
        if not math.isnan(self.restitution_minus):
            out["restitution_minus"] = self.restitution_minus / self.restitution_target_minus - 1.0
            out["quarter_period_minus"] = self.quarter_period_minus_s / self.quarter_period_closed_form_minus_s - 1.0
        if self.slenderness_deg is not None and self.slenderness_measured_deg is not None:
            for side in ("plus", "minus"):
                out[f"slenderness_{side}_deg"] = self.slenderness_measured_deg[side] - self.slenderness_deg[side]
        return out

    def to_json(self) -> dict[str, object]:
        return {**asdict(self), "errors": self.errors()}


def free_rocking(specimen: Specimen, seconds: float = 3.0, side: float = 1.0) -> tuple[float, float]:
    """(restitution, quarter period [s]) from a release at θ0 = α/2 on the ``side`` (±1) edge, α that side's
    slenderness; the restitution is that of the impact ending rocking on that corner (module docstring)."""
    body = specimen.body
    alpha, k = (body.alpha_plus, body.k_plus) if side > 0 else (body.alpha_minus, body.k_minus)
    alpha_o, k_o = (body.alpha_minus, body.k_minus) if side > 0 else (body.alpha_plus, body.k_plus)
    lean = 0.5 * alpha
    scene = SpecimenScene([specimen])
    scene.place(leans=[side * lean])
    n = round(seconds / SAMPLE)
    times = np.arange(1, n + 1) * SAMPLE
    angles = np.empty(n)
    still = np.zeros(6)
    for j in range(n):
        scene.advance(float(times[j]), still, still)
        angles[j] = side * scene.specimen_angles()[0]  # on the release side: > 0
    crossed = np.flatnonzero(angles <= 0.0)
    if crossed.size == 0:
        raise RuntimeError(f"{specimen.body.label()}: released at {lean:.4f} rad it did not rock back in {seconds} s")
    i = int(crossed[0])
    before, after = (lean, 0.0) if i == 0 else (angles[i - 1], times[i - 1])
    quarter = after + (times[i] - after) * before / (before - angles[i])
    window = angles[i:i + round(2.0 / SAMPLE)]
    other = -float(window.min())
    # ω² at θ = 0 from each side's energy: 2 g k (cos(α − θ_peak) − cos α)
    energy = k * (math.cos(alpha - lean) - math.cos(alpha))
    restitution = math.sqrt(max(0.0, k_o * (math.cos(alpha_o - other) - math.cos(alpha_o))) / energy)
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
    """Every measurement of the module docstring for ``specimen`` (alone, centred on the plate) at the tilt
    ``tilt`` [rad], on each side."""
    body = specimen.body
    a_p, a_m = body.alpha_plus, body.alpha_minus
    if not 0.0 <= tilt < a_p:
        raise ValueError(f"{body.label()}: the tilt {math.degrees(tilt):g}° must be below its α+ "
                         f"{math.degrees(a_p):.2f}° (it would not stand)")
    alone = replace(specimen, x=0.0, y=0.0)
    restitution, quarter = free_rocking(alone)
    restitution_m, quarter_m = free_rocking(alone, side=-1.0)
    low, high = math.tan(a_p - tilt), math.tan(a_m + tilt)
    uplift = {"low": _ramp(alone, tilt, -1.0, "rock", 1.5 * low + 0.05),
              "high": _ramp(alone, tilt, +1.0, "rock", 1.5 * high + 0.05)}
    mu = min(specimen.friction, 0.5 * math.tan(min(a_p, a_m)))
    sliding = _ramp(replace(alone, friction=mu), 0.0, +1.0, "slide",
                    1.5 * mu + 0.05)
    housner_p, housner_m = alone.housner_restitutions
    set_to = specimen.restitution
    return Characterisation(
        body=body.label(), b=body.b, h=body.h, alpha_deg=math.degrees(body.alpha), friction=specimen.friction,
        restitution=restitution, restitution_housner=housner_p,
        restitution_target=housner_p if set_to is None else set_to,
        quarter_period_s=quarter, quarter_period_closed_form_s=math.acosh(2.0) / body.p_plus,
        tilt_deg=math.degrees(tilt), uplift_g=uplift, uplift_eq1_g={"low": low, "high": high},
        sliding_g=sliding, sliding_mu=mu, b_cg=body.cg[0], h_cg=body.cg[1],
        slenderness_deg={"plus": math.degrees(a_p), "minus": math.degrees(a_m)},
        slenderness_measured_deg={"plus": math.degrees(math.atan(uplift["low"]) + tilt),
                                  "minus": math.degrees(math.atan(uplift["high"]) - tilt)},
        restitution_minus=restitution_m, restitution_housner_minus=housner_m,
        restitution_target_minus=housner_m if set_to is None else set_to,
        quarter_period_minus_s=quarter_m, quarter_period_closed_form_minus_s=math.acosh(2.0) / body.p_minus)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m sim_table.characterise",
                                description="Characterise the emulator's specimens against the closed forms.")
    p.add_argument("--body", action="append", default=[], metavar="BxH[;mu=F][;restitution=E][;cg=BCG,HCG]",
                   help="a body b×h [m], optionally its friction coefficient (else --friction), measured "
                        "restitution (the target of its impacts; else Housner's) and centre of gravity (b_cg from "
                        "the base's -x corner, h_cg above the base [m]); the emulator's --body syntax")
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

        def target(value: float, housner: float) -> str:
            return f"Housner {housner:.3f}" if value == housner else f"set {value:.3f}, Housner {housner:.3f}"

        assert r.slenderness_deg is not None and r.slenderness_measured_deg is not None
        print(f"{r.body} (centre of mass b_cg {1000 * r.b_cg:.1f} mm, h_cg {1000 * r.h_cg:.1f} mm): "
              f"restitution +x {r.restitution:.3f} ({target(r.restitution_target, r.restitution_housner)}, "
              f"{100 * e['restitution']:+.1f} %) / -x {r.restitution_minus:.3f} "
              f"({target(r.restitution_target_minus, r.restitution_housner_minus)}, "
              f"{100 * e['restitution_minus']:+.1f} %); quarter period +x {r.quarter_period_s:.4f} s (closed form "
              f"{r.quarter_period_closed_form_s:.4f} s, {100 * e['quarter_period']:+.1f} %) / -x "
              f"{r.quarter_period_minus_s:.4f} s ({r.quarter_period_closed_form_minus_s:.4f} s, "
              f"{100 * e['quarter_period_minus']:+.1f} %); uplift at "
              f"{r.tilt_deg:g}° {r.uplift_g['low']:.4f} g low / {r.uplift_g['high']:.4f} g high (Eq. 1 "
              f"{r.uplift_eq1_g['low']:.4f} / {r.uplift_eq1_g['high']:.4f}, {100 * e['uplift_low']:+.1f} / "
              f"{100 * e['uplift_high']:+.1f} %): slenderness +x {r.slenderness_measured_deg['plus']:.2f}° / -x "
              f"{r.slenderness_measured_deg['minus']:.2f}° (the body's {r.slenderness_deg['plus']:.2f}° / "
              f"{r.slenderness_deg['minus']:.2f}°); sliding {r.sliding_g:.4f} g at μ {r.sliding_mu:.3f} "
              f"({100 * e['sliding']:+.1f} %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
