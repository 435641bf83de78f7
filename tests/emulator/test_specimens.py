"""The emulator's physical specimens: MuJoCo bodies on the driven plate against the physics truths.

Plate motions are fed as the emulator does, one pose and pose rate every millisecond, with the pose and its
rate consistent (the rate is the pose's exact derivative).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import numpy as np
import pytest

from analysis import TABLE_V, Body
from analysis.body import G
from analysis.simulate import simulate
from analysis.table.model import rotation_matrices
from sim_table.scene import ContactSettings, Specimen, SpecimenError, parse_body
from sim_table.specimens import Overturn, SpecimenScene

Motion = Callable[[float], tuple[np.ndarray, np.ndarray]]

SAMPLE = 1e-3
"""Plate update interval of the emulator [s]."""

BETA = math.radians(7.0)


def still(pose: np.ndarray | None = None) -> Motion:
    """The plate held at ``pose`` (default home)."""
    held = np.zeros(6) if pose is None else pose
    return lambda t: (held, np.zeros(6))


def constant_acceleration(a_x: float) -> Motion:
    """Surge of the level plate from rest at a constant acceleration ``a_x`` [m/s²]."""

    def motion(t: float) -> tuple[np.ndarray, np.ndarray]:
        return np.array([0.5 * a_x * t * t, 0, 0, 0, 0, 0.0]), np.array([a_x * t, 0, 0, 0, 0, 0.0])

    return motion


def drive(scene: SpecimenScene, motion: Motion, duration: float,
          until: Callable[[SpecimenScene], bool] | None = None) -> list[Overturn]:
    """Feed ``motion`` for ``duration`` s from the scene's clock; all overturns :meth:`advance` returned."""
    start, found = scene.time, []
    for k in range(1, round(duration / SAMPLE) + 1):
        t = start + k * SAMPLE
        found.extend(scene.advance(t, *motion(t - start)))
        if until is not None and until(scene):
            break
    return found


def test_plate_follows_the_pose_convention() -> None:
    """Plate joints reproduce Rz·Ry·Rx and the pose rates; bodies are placed standing on the plate."""
    pose = np.array([0.05, -0.03, 0.02, 0.04, BETA, -0.3])
    scene = SpecimenScene([Specimen(TABLE_V[1], x=0.2, y=-0.1)], plate_pose=pose)
    d, plate = scene.data, scene.model.body("plate").id
    np.testing.assert_allclose(d.xmat[plate].reshape(3, 3), rotation_matrices(pose), atol=1e-12)
    np.testing.assert_allclose(d.xpos[plate], pose[:3], atol=1e-12)
    np.testing.assert_allclose(scene.specimen_angles(), [0.0], atol=1e-12)
    np.testing.assert_allclose(scene.specimen_places(), [[0.2, -0.1]], atol=1e-12)

    rate = np.array([0.1, 0.05, -0.02, 0.01, -0.02, 0.05])
    drive(scene, lambda t: (pose + rate * t, rate), 0.2)
    end = pose + rate * 0.2
    np.testing.assert_allclose(d.xmat[plate].reshape(3, 3), rotation_matrices(end), atol=1e-9)
    np.testing.assert_allclose(d.xpos[plate], end[:3], atol=1e-9)


def test_v2_free_rocking_first_impact(v_body: Body) -> None:
    """VALIDATION V2: released at rest at θ0 = 0.1 on its corner, θ returns to 0 at 0.6592522 s, θ' = −0.3456887."""
    scene = SpecimenScene([Specimen(v_body, friction=1.0)])
    scene.place(leans=[0.1])
    times, angles = [0.0], [0.1]

    def record(s: SpecimenScene) -> bool:
        times.append(s.time)
        angles.append(float(s.specimen_angles()[0]))
        return angles[-1] <= 0.0

    drive(scene, still(), 1.0, until=record)
    (t0, t1), (a0, a1) = times[-2:], angles[-2:]
    t_impact = t0 + (t1 - t0) * a0 / (a0 - a1)
    assert abs(t_impact / 0.6592522 - 1.0) < 0.02
    # the rate over the last sample interval before the impact (θ'' changes it by ~0.1 % there)
    rate = (angles[-2] - angles[-3]) / (times[-2] - times[-3])
    assert abs(rate / -0.3456887 - 1.0) < 0.01


OFF_CENTRE = Body(0.2, 0.8, b_cg=0.13, h_cg=0.35, depth=0.4, mass=20.0)
"""A block whose centre of mass is well off its centroid (α+ = 11.3°, α− = 20.4°)."""


def test_an_off_centre_specimen_carries_its_centre_of_mass_and_the_uniform_boxs_inertia_about_it() -> None:
    scene = SpecimenScene([Specimen(OFF_CENTRE, x=0.1, y=0.2)])
    m, i = scene.model, scene.model.body("specimen0").id
    np.testing.assert_allclose(m.body_ipos[i], [0.13 - 0.1, 0.0, 0.35 - 0.4], atol=1e-15)
    assert m.body_mass[i] == pytest.approx(20.0)
    np.testing.assert_allclose(sorted(m.body_inertia[i]), sorted([20.0 * (0.4**2 + 0.8**2) / 12,
                                                                  20.0 * (0.2**2 + 0.8**2) / 12,
                                                                  20.0 * (0.2**2 + 0.4**2) / 12]), rtol=1e-12)
    np.testing.assert_allclose(scene.specimen_places(), [[0.1 + 0.03, 0.2]], atol=1e-12)  # under the centre of mass
    # a centred body keeps the box geom's own (centred) inertia
    plain = SpecimenScene([Specimen(Body(0.2, 0.8))])
    np.testing.assert_allclose(plain.model.body_ipos[plain.model.body("specimen0").id], 0.0, atol=1e-15)


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_free_rocking_on_each_corner_of_an_off_centre_body_matches_the_analysis(side: float) -> None:
    """Released at rest at half its slenderness on each corner, the specimen reaches θ = 0 when the analysis's
    reference solver (each corner's α, R and the uniform box's i_g about the centre of mass) says, at its rate."""
    alpha = OFF_CENTRE.alpha_plus if side > 0 else OFF_CENTRE.alpha_minus
    lean = side * 0.5 * alpha
    ref = simulate(OFF_CENTRE, np.zeros(3), 0.01, solver="reference", theta0=lean, t_after=2.0)
    t_ref, om_ref = ref.trace.impacts[0][0], ref.trace.impacts[0][1]
    scene = SpecimenScene([Specimen(OFF_CENTRE, friction=1.0)])
    scene.place(leans=[lean])
    times, angles = [0.0], [lean]

    def record(s: SpecimenScene) -> bool:
        times.append(s.time)
        angles.append(float(s.specimen_angles()[0]))
        return side * angles[-1] <= 0.0

    drive(scene, still(), 2.0, until=record)
    (t0, t1), (a0, a1) = times[-2:], angles[-2:]
    t_impact = t0 + (t1 - t0) * a0 / (a0 - a1)
    assert abs(t_impact / t_ref - 1.0) < 0.02
    rate = (angles[-2] - angles[-3]) / (times[-2] - times[-3])
    assert abs(rate / om_ref - 1.0) < 0.01
    # the two corners differ by more than that
    other = simulate(OFF_CENTRE.mirrored(), np.zeros(3), 0.01, solver="reference", theta0=lean, t_after=2.0)
    assert abs(other.trace.impacts[0][0] / t_ref - 1.0) > 0.05


def test_the_emulators_body_syntax_takes_the_centre_of_gravity() -> None:
    placed = parse_body("0.2x0.8@0.1,0.2;mass=20;cg=0.13,0.35")
    assert placed.body.cg == (0.13, 0.35) and placed.body.mass == 20.0 and (placed.x, placed.y) == (0.1, 0.2)
    assert parse_body("0.2x0.8").body.centred
    for bad, words in (("0.2x0.8;cg=0.13", "cg=BCG,HCG"), ("0.2x0.8;cg=0.2,0.35", "0 < b_cg < b"),
                       ("0.2x0.8;cg=0.1,0.9", "0 < h_cg < h"), ("0.2x0.8;cg=a,b", "cg=BCG,HCG")):
        with pytest.raises(SpecimenError, match=words):
            parse_body(bad)


@pytest.mark.parametrize(("a_x", "direction"), [(-0.5 * G, +1), (0.5 * G, -1)])
def test_sign_convention_long_plate_acceleration(a_x: float, direction: int) -> None:
    """docs/architecture.md §2: uphill plate acceleration (a_x < 0) tips a slender body towards +x (+1)."""
    scene = SpecimenScene([Specimen(Body(0.1, 0.5), friction=1.0)])
    found = drive(scene, constant_acceleration(a_x), 1.5)
    assert [(e.body_id, e.direction) for e in found] == [(0, direction)]
    assert 0.1 < found[0].t < 1.0
    assert math.copysign(1.0, scene.specimen_angles()[0]) == direction


def test_body_stands_still_on_a_tilted_plate() -> None:
    """Placed on a 7° plate with α = 0.254 > β and μ = 0.8, a body neither rotates nor slides."""
    body = TABLE_V[1]
    assert body.alpha > BETA
    pose = np.array([0.0, 0.0, 0.0, 0.0, BETA, 0.0])
    scene = SpecimenScene([Specimen(body, x=-0.2, friction=0.8)], plate_pose=pose)
    assert drive(scene, still(pose), 4.0) == []
    assert abs(scene.specimen_angles()[0]) < 1e-4
    np.testing.assert_allclose(scene.specimen_places(), [[-0.2, 0.0]], atol=1e-4)


def test_tilting_plate_tips_the_body_whose_alpha_is_below_beta_downhill() -> None:
    """Tilting at 2°/s to 7°: the body with α = 5.7° tips towards +x once β passes α; the stout one stands."""
    rate, slender = math.radians(2.0), Body(0.04, 0.4)
    ramp_end = BETA / rate

    def tilt(t: float) -> tuple[np.ndarray, np.ndarray]:
        if t < ramp_end:
            return np.array([0, 0, 0, 0, rate * t, 0.0]), np.array([0, 0, 0, 0, rate, 0.0])
        return np.array([0, 0, 0, 0, BETA, 0.0]), np.zeros(6)

    scene = SpecimenScene([Specimen(slender, y=-0.3, friction=0.8), Specimen(TABLE_V[1], y=0.3, friction=0.8)])
    found = drive(scene, tilt, ramp_end + 2.0)
    assert [(e.body_id, e.direction) for e in found] == [(0, +1)]
    assert found[0].t > slender.alpha / rate
    assert abs(scene.specimen_angles()[1]) < 1e-4


def test_friction_drags_the_body_with_the_plate() -> None:
    """At 0.1 g, below uplift (g·tan α ≈ 0.2 g) and sliding (μg), the body keeps the plate's acceleration."""
    a, duration = 0.1 * G, 1.0
    scene = SpecimenScene([Specimen(Body(0.1, 0.5), friction=0.8)])
    drive(scene, constant_acceleration(a), duration)
    # the plate travels a·T²/2 = 0.49 m; a body accelerating at (1 − ε)·a would lag it by ε·0.49 m
    assert abs(scene.specimen_places()[0, 0]) < 1e-4
    assert abs(scene.specimen_angles()[0]) < 1e-3


def test_friction_above_mu_g_lets_the_body_slide_at_mu_g() -> None:
    """At 0.4 g on μ = 0.2 a squat body slides: it accelerates at μg, lagging the plate by (a − μg)T²/2."""
    a, mu, duration = 0.4 * G, 0.2, 0.5
    scene = SpecimenScene([Specimen(Body(0.4, 0.4), friction=mu)])
    drive(scene, constant_acceleration(a), duration)
    expected = -(a - mu * G) * 0.5 * duration**2
    assert scene.specimen_places()[0, 0] == pytest.approx(expected, rel=0.03)


def test_each_overturn_is_reported_once_per_placement() -> None:
    """A fallen body stays reported once while the plate keeps shaking; placing it again re-arms detection."""
    scene = SpecimenScene([Specimen(Body(0.1, 0.5), friction=0.8)])

    def shake(t: float) -> tuple[np.ndarray, np.ndarray]:
        w, amp = 2 * math.pi * 3.0, 0.02
        x, v = amp * (1 - math.cos(w * t)), amp * w * math.sin(w * t)
        return np.array([x, 0, 0, 0, 0, 0.0]), np.array([v, 0, 0, 0, 0, 0.0])

    scene.place(leans=[0.6])
    found = drive(scene, shake, 2.0)
    assert [(e.body_id, e.direction) for e in found] == [(0, +1)]
    assert scene.detections() == found
    scene.place(plate_pose=np.zeros(6), leans=[-0.6])
    assert scene.detections() == []
    again = drive(scene, shake, 1.5)
    assert [(e.body_id, e.direction) for e in again] == [(0, -1)]
    assert again[0].t > found[0].t


def test_table_v_bodies_on_one_plate_are_tracked_separately() -> None:
    """Seven Table V bodies side by side: the leaned ones fall their own way, the others stand."""
    leans = [0.6, 0.0, -0.6, 0.0, 0.6, 0.0, -0.6]
    specimens = [Specimen(body, y=0.6 * (i - 3), friction=0.8) for i, body in enumerate(TABLE_V)]
    scene = SpecimenScene(specimens)
    scene.place(leans=leans)
    found = drive(scene, still(), 1.5)
    assert sorted((e.body_id, e.direction) for e in found) == [(0, 1), (2, -1), (4, 1), (6, -1)]
    assert [e.t for e in found] == sorted(e.t for e in found)
    angles = scene.specimen_angles()
    np.testing.assert_allclose(angles[1::2], 0.0, atol=1e-4)
    np.testing.assert_allclose(np.abs(angles[0::2]), 0.5 * math.pi, atol=0.05)


def test_table_v_bodies_shaken_together_are_each_reported_as_they_lie() -> None:
    """Seven Table V bodies in a row on a 5° plate under a 6 s multi-sine: some fall (onto each other too).

    Whatever the chaotic outcome, every body is reported at most once, in time order, in the direction it
    lies, and no body that is still standing is reported.
    """
    beta, duration = math.radians(5.0), 5.0
    w = 2 * math.pi * np.array([1.1, 1.9, 3.3])
    amplitude = 0.8 * np.array([0.15, 0.12, 0.08]) * G / w**2
    phase = np.array([0.3, 1.7, 4.0])

    def quake(t: float) -> tuple[np.ndarray, np.ndarray]:
        if t >= duration:
            return np.array([0, 0, 0, 0, beta, 0.0]), np.zeros(6)
        envelope = math.sin(math.pi * t / duration) ** 2
        envelope_rate = math.pi / duration * math.sin(2 * math.pi * t / duration)
        x, v = -np.sum(amplitude * np.sin(w * t + phase)), -np.sum(amplitude * w * np.cos(w * t + phase))
        return (np.array([envelope * x, 0, 0, 0, beta, 0.0]),
                np.array([envelope_rate * x + envelope * v, 0, 0, 0, 0, 0.0]))

    specimens = [Specimen(body, x=-1.2 + 0.42 * i, friction=0.8) for i, body in enumerate(TABLE_V)]
    scene = SpecimenScene(specimens, plate_pose=[0, 0, 0, 0, beta, 0])
    found = drive(scene, quake, duration + 1.0)
    assert np.all(np.isfinite(scene.data.qpos))
    assert found == scene.detections()
    assert [e.t for e in found] == sorted(e.t for e in found)
    fallen = {e.body_id: e.direction for e in found}
    assert len(fallen) == len(found)
    angles = scene.specimen_angles()
    for i, angle in enumerate(angles):
        threshold = scene.thresholds[i, 0 if angle >= 0 else 1]  # the side it leans to
        if i in fallen:
            assert math.copysign(1, angle) == fallen[i] and abs(angle) >= threshold
        else:
            assert abs(angle) < threshold
    assert 0 < len(fallen) < len(specimens)


def test_default_mass_and_depth() -> None:
    """Without depth and mass a specimen is 2·b deep and of agglomerated wood (600 kg/m³)."""
    s = Specimen(Body(0.1, 0.5))
    assert s.depth == pytest.approx(0.2)
    assert s.mass == pytest.approx(600.0 * 0.1 * 0.5 * 0.2)
    assert Specimen(TABLE_V[0]).mass == TABLE_V[0].mass


def test_bad_input_is_refused() -> None:
    body = Body(0.1, 0.5)
    with pytest.raises(SpecimenError, match="overlap"):
        SpecimenScene([Specimen(body), Specimen(body, x=0.05)])
    with pytest.raises(SpecimenError, match="at least one"):
        SpecimenScene([])
    with pytest.raises(SpecimenError, match="friction"):
        Specimen(body, friction=0.0)
    with pytest.raises(SpecimenError, match="twice the timestep"):
        ContactSettings(timestep=1e-3, time_constant=1e-3)
    scene = SpecimenScene([Specimen(body)])
    with pytest.raises(SpecimenError, match="6 finite values"):
        scene.advance(0.001, np.zeros(5), np.zeros(6))
    with pytest.raises(SpecimenError, match="time must increase"):
        scene.advance(0.0, np.zeros(6), np.zeros(6))
    with pytest.raises(SpecimenError, match="leans"):
        scene.place(leans=[0.1, 0.2])


def test_advance_many_steps_the_batch_as_advance_steps_each_sample() -> None:
    """The emulator's batched stepping (``advance_many``: the plate put on its curve once a batch, the physics
    stepped in C) against :meth:`advance` sample by sample (the stepping V2 checks): Table V bodies on a plate that
    tilts to 5° then shakes, in batches of 40 samples and of uneven sizes. Until the first body falls the states
    agree within 1e-5 (m, quaternion); then the same bodies fall, the same way, within half a step (impacts amplify
    rounding: the fallen bodies' states differ by ~1 mm), and the plate stays on its curve within 1e-6."""
    beta, t = math.radians(5.0), np.arange(1, 2501) * SAMPLE
    poses, rates = np.zeros((len(t), 6)), np.zeros((len(t), 6))
    ramp = np.clip(t, 0.0, 1.0)
    poses[:, 4], rates[:, 4] = beta * ramp**2 * (3 - 2 * ramp), beta * 6 * ramp * (1 - ramp)
    shake = 2 * math.pi * 2.0
    poses[:, 0] = np.where(t > 1.0, 0.03 * np.sin(shake * (t - 1.0)), 0.0)
    rates[:, 0] = np.where(t > 1.0, 0.03 * shake * np.cos(shake * (t - 1.0)), 0.0)
    specimens = [Specimen(body, y=-1.8 + 0.6 * i) for i, body in enumerate(TABLE_V)]  # a row across the fall line
    calm = 1200  # samples before the first fall
    for cuts in (range(0, len(t), 40), [0, 1, 7, 300, 301, 1200, 2001]):
        one, many = SpecimenScene(specimens), SpecimenScene(specimens)
        bounds = [*cuts, len(t)]
        each, batched = [], []
        for a, b in itertools.pairwise(bounds):
            batched += many.advance_many(t[a:b], poses[a:b], rates[a:b])
            each += [e for k in range(a, b) for e in one.advance(t[k], poses[k], rates[k])]
            if b == calm:
                assert not each and not batched
                np.testing.assert_allclose(many.data.qpos, one.data.qpos, atol=1e-5)
        assert len(each) >= 2  # bodies fell
        assert [(e.body_id, e.direction) for e in batched] == [(e.body_id, e.direction) for e in each]
        np.testing.assert_allclose([e.t for e in batched], [e.t for e in each], atol=0.5 * SAMPLE)
        np.testing.assert_allclose(many.data.qpos[:6], one.data.qpos[:6], atol=1e-6)
        assert many.time == one.time and many.detections() == batched


def test_sample_angles_are_each_bodys_angle_at_every_sample_time_fallen_bodies_included() -> None:
    """The tilt sensor's channel (``sample_angles``): two bodies released leaning ±0.6 rad and one standing on a
    still plate, fed in batches (and one interval shorter than a step). Each batch's rows are the angles at its
    sample times, as :meth:`advance` sample by sample gives them while nothing has fallen; a fallen body keeps being
    reported, lying on its side in its direction; the standing one stays at 0."""
    specimens = [Specimen(Body(0.1, 0.5), y=-0.6 + 0.6 * i, friction=0.8) for i in range(3)]
    one, many = SpecimenScene(specimens), SpecimenScene(specimens)
    leans = [0.6, 0.0, -0.6]
    one.place(leans=leans)
    many.place(leans=leans)
    assert many.sample_angles.shape == (0, 3)
    t = np.arange(1, 1501) * SAMPLE
    pose = np.zeros((len(t), 6))
    each, batched, found = [], [], []
    for a, b in itertools.pairwise([*range(0, len(t), 40), len(t)]):
        found += many.advance_many(t[a:b], pose[a:b], pose[a:b])
        assert many.sample_angles.shape == (b - a, 3)
        np.testing.assert_allclose(many.sample_angles[-1], many.specimen_angles(), atol=1e-12)
        batched.append(many.sample_angles)
        for k in range(a, b):
            one.advance(t[k], pose[k], pose[k])
            assert one.sample_angles.shape == (1, 3)
            each.append(one.sample_angles[0])
    batched, each = np.vstack(batched), np.array(each)
    first_fall = round(found[0].t / SAMPLE)
    np.testing.assert_allclose(batched[:first_fall], each[:first_fall], atol=1e-5)
    np.testing.assert_allclose(batched[0], leans, atol=0.02)  # released at rest where they leaned
    assert sorted((e.body_id, e.direction) for e in found) == [(0, 1), (2, -1)]
    np.testing.assert_allclose(batched[-1], [0.5 * math.pi, 0.0, -0.5 * math.pi], atol=0.05)
    assert np.abs(batched[:, 1]).max() < 1e-4
    before = many.sample_angles[-1]
    many.advance_many(t[-1] + np.array([0.4, 1.0]) * SAMPLE, pose[:2], pose[:2])  # the first too short for a step
    np.testing.assert_array_equal(many.sample_angles[0], before)
    assert many.time == pytest.approx(t[-1] + SAMPLE)


def test_the_paper_campaigns_specimens_are_not_housners() -> None:
    """``examples/paper-campaign.toml`` gives each Table V body the restitution free-rocking tests measured for
    blocks of its aspect ratio (docs/specimens.md: ElGawady et al., about 0.95 of Housner's at h/b = 5 and 0.97 at
    h/b = 3, linear between, the end values outside), to three decimals: every one 3–5 % below Housner's."""
    import tomllib
    from pathlib import Path

    campaign = tomllib.loads((Path(__file__).resolve().parents[2] / "examples/paper-campaign.toml").read_text())
    assert [body["table5"] for body in campaign["bodies"]] == list(range(1, 8))
    for body in campaign["bodies"]:
        block = TABLE_V[body["table5"] - 1]
        aspect = min(max(block.h / block.b, 3.0), 5.0)
        ratio = 0.97 + (aspect - 3.0) / 2.0 * (0.95 - 0.97)
        housner = 1.0 - 1.5 * math.sin(math.atan(block.b / block.h)) ** 2
        assert body["restitution"] == pytest.approx(ratio * housner, abs=5e-4), block.name
        assert 0.95 <= body["restitution"] / housner <= 0.97, block.name
