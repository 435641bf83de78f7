"""Sequence files: the examples load and pass the check before anything moves; every class of bad file is
refused with the key and its line; plan order; JSON round trip."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import pytest

from analysis.body import TABLE_V
from analysis.table.toml_lines import dotted_path, key_lines
from rig.emulator import specimen_flags
from rig.sequence import PlannedRun, Sequence, SequenceError, load_sequence, record_of_label
from sim_table.scene import parse_body

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

# A small valid sequence; the line numbers below are asserted in the error tests.
BASE = """\
name = "t"
angles_deg = [0, 5]
records = [
    "fema-farfield:KOBE/NIS000",
    { record = "fema-nearfield:NORTHR/RRS_032", window_s = [0.5, 5.5] },
]

[drive]
corner_hz = 1.0

[[bodies]]
table5 = 4
x = 0.0
y = -0.15

[[bodies]]
name = "B"
b = 0.049
h = 0.2
depth = 0.109
mass = 0.56
x = 0.0
y = 0.15
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "seq.toml"
    path.write_text(text)
    return path


def replace_line(line: int, new: str, text: str = BASE) -> str:
    """``text`` with its 1-based ``line`` replaced by ``new`` (which may hold several lines, or none)."""
    lines = text.splitlines()
    lines[line - 1:line] = new.splitlines()
    return "\n".join(lines) + "\n"


def refused(tmp_path: Path, text: str, *, check: bool = False) -> SequenceError:
    path = write(tmp_path, text)
    with pytest.raises(SequenceError) as caught:
        load_sequence(path).check() if check else load_sequence(path)
    return caught.value


# ----- the examples ----------------------------------------------------------------------------------------


def test_quick_example_loads_checks_and_fits_the_demo() -> None:
    seq = load_sequence(EXAMPLES / "quick.toml")
    assert len(seq.bodies) == 2 and seq.angles_deg == (0.0, 4.0) and len(seq.records) == 3
    assert [b.body_id for b in seq.bodies] == [1, 2]
    assert all(math.radians(max(seq.angles_deg)) < b.body.alpha for b in seq.bodies)
    assert all(entry.window is not None and entry.window[1] - entry.window[0] <= 10 for entry in seq.records)
    started = time.perf_counter()
    seq.check()
    assert time.perf_counter() - started < 10
    # 6 runs; the tilt ramps to 4° and back take 7.8 s of each tilted run
    assert len(seq.plan()) == 6
    assert seq.table_seconds() < 60.0
    assert seq.operator.confirm_before_run is False and seq.operator.ask_detections is False


def test_paper_campaign_loads_with_table_v_and_25_strongest_components() -> None:
    seq = load_sequence(EXAMPLES / "paper-campaign.toml")
    assert [b.body for b in seq.bodies] == list(TABLE_V)
    assert seq.angles_deg == (0.0, 4.0, 4.5, 5.0, 5.5)
    tap, records = seq.records[0], seq.records[1:]
    assert tap.key == "records[1]" and tap.spec.endswith("records/tap-10hz.csv")  # first at every angle
    assert tap.polarity == 1  # the tap as recorded only
    assert len(records) == 50 and len({e.spec for e in records}) == 25  # each record in both polarities
    assert [e.polarity for e in records] == [1, -1] * 25 and all(
        a.spec == b.spec for a, b in zip(records[::2], records[1::2], strict=True))
    assert all(e.spec.startswith(("fema-farfield:", "fema-nearfield:")) and e.scale is None for e in records)
    assert len(seq.plan()) == 255
    # every Table V body stands at 5.5°: α = atan(b/h) ≥ 11.0°
    assert min(math.degrees(b.body.alpha) for b in seq.bodies) > 11.0
    seq.check(prepare_drives=False)


def test_records_from_takes_the_largest_pga_first() -> None:
    from rig.records import load_record, load_records

    seq = load_sequence(EXAMPLES / "paper-campaign.toml")
    taken = [e for e in seq.records if e.key == "records_from" and e.polarity == 1]
    pgas = [load_record(e.spec).pga for e in taken]
    assert pgas == sorted(pgas, reverse=True)
    weakest_taken = pgas[-1]
    assert sum(m.pga > weakest_taken for m in load_records("fema")) <= 24
    assert all(e.line == 17 for e in taken)


def test_paper_campaign_every_drive_is_inside_the_table() -> None:
    seq = load_sequence(EXAMPLES / "paper-campaign.toml")
    seq.check()  # 255 drives, about 4-10 s


# ----- refusals: key and line ------------------------------------------------------------------------------


@pytest.mark.parametrize(("line", "new", "at", "message"), [
    # missing key: reported at the [[bodies]] header of that body
    (19, "", 16, "bodies[2].h: missing; expected a height from 0.001 m to 5 m (or table5 = N)"),
    # wrong types
    (19, 'h = "0.2"', 19, "bodies[2].h: expected a height from 0.001 m to 5 m, got '0.2'"),
    (13, "x = true", 13, "bodies[1].x: expected a finite number in metres, got True"),
    (2, 'angles_deg = "0, 5"', 2, "angles_deg: expected a non-empty list of plate angles in degrees"),
    (1, 'name = "t"\nrepetitions = 1.5', 2, "repetitions: expected a whole number from 1 to 100, got 1.5"),
    # unknown keys (typos) are refused, with a suggestion
    (20, "dpeth = 0.109", 20, "bodies[2].dpeth: unknown key (did you mean 'depth'?); expected one of"),
    (2, "angels_deg = [0, 5]", 2, "angels_deg: unknown key (did you mean 'angles_deg'?)"),
    (9, "corner = 1.0", 9, "drive.corner: unknown key (did you mean 'corner_hz'?)"),
    # a top-level key written after a [section] belongs to that section: say so
    (23, "y = 0.15\nrepetitions = 2", 24, "bodies[2].repetitions: unknown key (a top-level key: in TOML every key "
                                          "after a [section] header belongs to that section"),
    # zero and negative dimensions
    (18, "b = 0", 18, "bodies[2].b: expected a base width from 0.001 m to 3 m, got 0"),
    (21, "mass = -0.56", 21, "bodies[2].mass: expected a mass from 0.001 kg to 2000 kg, got -0.56"),
    (12, "table5 = 8", 12, "bodies[1].table5: expected a whole number from 1 to 7, got 8"),
    (12, "table5 = 4\nb = 0.04", 13, "bodies[1].b: give either table5 = N or the dimensions"),
    # empty, duplicated and out-of-range angles
    (2, "angles_deg = []", 2, "angles_deg: expected a non-empty list of plate angles in degrees"),
    (2, "angles_deg = [0,\n  5,\n  5]", 4, "angles_deg[3]: 5° is already angles_deg[2]"),
    (2, "angles_deg = [0, 12]", 2, "angles_deg[2]: expected an angle in degrees from 0 to the table's tilt limit 10°"),
    (2, "angles_deg = [-1]", 2, "angles_deg[1]: expected an angle in degrees from 0"),
    # overlapping bodies, a body off the plate
    (23, "y = -0.1", 22, "bodies[2].x: body 2 (B) overlaps body 1 (T5-4) on the plate"),
    (22, "x = 1.48", 22, "bodies[2].x: body 2 (B) does not fit on the plate: its base spans x = 1.456 … 1.504 m, "
                         "expected within ±1.5 m"),
    (17, 'name = "T5-4"', 17, "bodies[2].name: the name 'T5-4' is already body 1's"),
    (23, "y = 0.15\nrestitution = 1.2", 24,
     "bodies[2].restitution: expected the body's measured coefficient of restitution, in (0, 1], got 1.2"),
    (23, "y = 0.15\nrestitution = 0", 24, "bodies[2].restitution: expected the body's measured coefficient"),
    # the centre of gravity: inside the body, b_cg from the -x corner
    (21, "mass = 0.56\nb_cg = 0.049", 22, "bodies[2].b_cg: expected the centre of gravity from the base's -x "
                                          "(uphill) corner along +x in metres, inside the body: 0 < b_cg < b = "
                                          "0.049 m, got 0.049"),
    (21, "mass = 0.56\nh_cg = 0", 22, "bodies[2].h_cg: expected the centre of gravity above the base in metres, inside "
                                     "the body: 0 < h_cg < h = 0.2 m, got 0"),
    (21, 'mass = 0.56\nh_cg = "0.1"', 22, "bodies[2].h_cg: expected the centre of gravity above the base"),
    (12, "table5 = 4\nb_cg = 0.05", 13, "bodies[1].b_cg: expected the centre of gravity from the base's -x (uphill) "
                                       "corner along +x in metres, inside the body: 0 < b_cg < b = 0.039 m, got 0.05"),
    # record entries
    (5, '    { record = "fema-nearfield:NORTHR/RRS_032", scale = 1.5 },', 5,
     'records[2].scale: expected "table" or a fixed factor from 0.001 to 1, got 1.5'),
    (5, '    { record = "fema-nearfield:NORTHR/RRS_032", window_s = [5, 1] },', 5,
     "records[2].window_s: expected [t0, t1] in seconds of the record, 0 ≤ t0 < t1 ≤ 1200, got [5, 1]"),
    (5, '    { scale = 0.5 },', 5, "records[2].record: missing; expected"),
    (4, '    "fema-farfield:KOBE/NIS000",\n    "fema-farfield:KOBE/NIS000",', 5,
     "records[2]: fema-farfield:KOBE/NIS000 is already records[1] with the same options"),
    (6, ']\nrecords_from = { suite = "fema-far", strongest = 3 }', 7, "records_from.suite: unknown suite 'fema-far'"),
    (6, ']\nrecords_from = { suite = "fema", strongest = 101 }', 7,
     "records_from.strongest: strongest = 101 but suite 'fema' has 100 components"),
    # the rest of the file
    (1, 'name = "t"\ntable_url = "127.0.0.1:14600"', 2,
     "table_url: expected mavlink://HOST:PORT, zenoh://HOST:PORT/TABLE or canopen://CHANNEL?interface=NAME"),
    (9, 'corner_hz = 1.0\n[operator]\nplace_bodies = "at {angle}"', 11,
     "operator.place_bodies: placeholder {angle} is not one of {angle_deg}, {bodies}, {sequence}"),
    (9, "corner_hz = 1.0\n[rig]\nconfig = \"nowhere.toml\"", 11,
     "rig.config: the rig configuration is refused:"),
    (9, "corner_hz = 1.0\n[rig.limits.surge]\n\nvelocity_m_s = -0.5", 12,
     "rig.limits.surge.velocity_m_s: must be from 0.001 m/s to 5 m/s, got -0.5"),
    (9, "corner_hz = 1.0\n[plate]\nsize_m = [3, 0]", 11, "plate.size_m[2]: expected [x, y] in metres, "
                                                           "each from 0.1 m to 10 m"),
    # a missing top-level key is reported at line 1, where top-level keys belong
    (2, "", 1, "angles_deg: missing; expected a list of plate angles in degrees"),
    # TOML syntax
    (13, "x = ", 13, "TOML syntax error: Invalid value (column 5)"),
])
def test_bad_files_are_refused_at_load_with_key_and_line(tmp_path: Path, line: int, new: str, at: int,
                                                         message: str) -> None:
    error = refused(tmp_path, replace_line(line, new))
    assert str(error).startswith(f"{tmp_path}/seq.toml:{at}: {message}"), str(error)
    assert error.line == at


@pytest.mark.parametrize(("line", "new", "at", "message"), [
    # unknown record (with the suite's suggestion)
    (4, '    "fema-farfield:KOBE/NIS999",', 4,
     "records[1]: fema-farfield:KOBE/NIS999: no record 'KOBE/NIS999' in suite 'fema-farfield'. Did you mean"),
    (4, '    "nowhere/at/all.AT2",', 4, "records[1]: nowhere/at/all.AT2: "),
    # a window past the record's end
    (5, '    { record = "fema-nearfield:NORTHR/RRS_032", window_s = [0.5, 99] },', 5,
     "records[2]: fema-nearfield:NORTHR/RRS_032 [0.5-99 s]: window_s = [0.5, 99] s ends after the record"),
    # a fixed scale that drives the table outside Table IV: the record's line and the violation
    (5, '    { record = "fema-nearfield:NORTHR/RRS_032", window_s = [0.5, 5.5], scale = 0.9 },', 5,
     "records[2]: fema-nearfield:NORTHR/RRS_032 [0.5-5.5 s]: at β = 0° the fixed scale is refused: scale factor 0.9 "
     "is outside (0, 0.6965]: surge velocity would reach 0.6461 against the limit 0.5"),
])
def test_bad_sequences_are_refused_by_the_check_with_key_and_line(tmp_path: Path, line: int, new: str, at: int,
                                                                  message: str) -> None:
    error = refused(tmp_path, replace_line(line, new), check=True)
    assert str(error).startswith(f"{tmp_path}/seq.toml:{at}: {message}"), str(error)


SLENDER = replace_line(19, "h = 0.5")  # body 2: α = atan(0.049 / 0.5) = 5.60°


@pytest.mark.parametrize(("angles", "at", "key", "angle"), [
    ("angles_deg = [0,\n    4,\n    9.5]", 4, "angles_deg[3]", "9.5"),
    ("angles_deg = [5.6, 0]", 2, "angles_deg[1]", "5.6"),
])
def test_an_angle_a_body_cannot_stand_at_is_refused(tmp_path: Path, angles: str, at: int, key: str,
                                                    angle: str) -> None:
    error = refused(tmp_path, replace_line(2, angles, SLENDER), check=True)
    assert str(error) == (f"{tmp_path}/seq.toml:{at}: {key}: body 2 (B, b = 0.049 m, h = 0.5 m) cannot stand at "
                          f"β = {angle}°: its slenderness angle α = atan(b/h) = 5.60°, and a block tips over once "
                          "β ≥ α (expected β < 5.60°)")


def test_a_drive_outside_the_legs_stroke_is_refused_with_the_violation(tmp_path: Path) -> None:
    # the default hexapod with a stroke that ends 7 mm above the home leg length (2.208 m)
    hexapod = ("corner_hz = 1.0\n[rig.hexapod]\nbase_radius_m = 1.6\nplatform_radius_m = 1.1\n"
               "base_half_angle_deg = 10\nplatform_half_angle_deg = 10\nplatform_joint_depth_m = 0.15\n"
               "home_height_m = 2.1\nleg_min_m = 1.6\nleg_max_m = 2.215\nleg_speed_m_s = 0.9")
    error = refused(tmp_path, replace_line(9, hexapod), check=True)
    assert str(error).startswith(f"{tmp_path}/seq.toml:4: records[1]: fema-farfield:KOBE/NIS000: at β = 0° the drive "
                                 "leaves the table: at t = "), str(error)
    assert "exceeds the stroke limit 2.2150 m" in str(error)


def test_prepare_refuses_a_run_whose_angle_a_body_cannot_stand_at(tmp_path: Path) -> None:
    seq = load_sequence(write(tmp_path, replace_line(2, "angles_deg = [0, 5, 6]", SLENDER)))
    runs = seq.plan()
    drive = seq.prepare(runs[0])
    assert drive.angle == 0.0 and drive.record == "KOBE/NIS000"
    with pytest.raises(SequenceError, match=r"seq.toml:2: angles_deg\[3\]: body 2 \(B, .*cannot stand at β = 6°"):
        seq.prepare(runs[-1])


def test_windowed_record_is_cut_and_its_drive_starts_and_ends_at_rest(tmp_path: Path) -> None:
    seq = load_sequence(write(tmp_path, BASE))
    motion = seq.motion(1)
    assert motion.name == "NORTHR/RRS_032 [0.5-5.5 s]"
    assert motion.duration == pytest.approx(5.0, abs=motion.dt)
    assert motion.provenance["window_s"] == [0.5, 5.5] and motion.provenance["sha256"] != \
        motion.provenance["record_sha256"]
    drive = seq.prepare(seq.plan()[3])  # RRS at 5°
    assert drive.corner_frequency == 1.0 and drive.angle == pytest.approx(math.radians(5))
    rest = [0, 0, 0, 0, math.radians(5), 0]  # the table is tilted once per angle: the drive starts and ends there
    assert np.array_equal(drive.poses[0], rest) and np.array_equal(drive.poses[-1], rest)
    assert abs(drive.velocities[[0, -1]]).max() < 1e-9


def test_paths_are_read_from_the_sequence_folder_and_the_rig_config_applies(tmp_path: Path) -> None:
    (tmp_path / "rig.toml").write_text("[limits.tilt]\nangle_deg = 6\n")
    record = tmp_path / "rec.txt"
    record.write_text("\n".join(f"{0.1 * math.sin(0.5 * k):.6f}" for k in range(800)) + "\n")
    text = replace_line(4, '    { record = "rec.txt", dt_s = 0.01, units = "g" },')
    text = replace_line(9, 'corner_hz = 1.0\n[rig]\nconfig = "rig.toml"', text)
    seq = load_sequence(write(tmp_path, text))
    assert seq.records[0].resolved == str(record)
    assert seq.table.limits.tilt.angle == pytest.approx(math.radians(6))
    seq.check()
    error = refused(tmp_path, replace_line(2, "angles_deg = [0, 7]", text))
    assert str(error).startswith(f"{tmp_path}/seq.toml:2: angles_deg[2]: expected an angle in degrees from 0 to the "
                                 "table's tilt limit 6°")


# ----- plan and JSON ---------------------------------------------------------------------------------------


def test_plan_order_and_indices(tmp_path: Path) -> None:
    seq = load_sequence(write(tmp_path, replace_line(1, 'name = "t"\nrepetitions = 2')))
    plan = seq.plan()
    assert [r.plan_index for r in plan] == list(range(8))
    assert [(r.angle_deg, r.record_index, r.repetition) for r in plan] == [
        (a, r, k) for a in (0.0, 5.0) for r in (0, 1) for k in (0, 1)]
    assert plan[5] == PlannedRun(5, 1, 5.0, 0, seq.records[0], 1)
    assert plan == seq.plan()  # stable
    assert json.loads(json.dumps([run.to_dict() for run in plan]))[7] == {
        "plan_index": 7, "angle_index": 1, "angle_deg": 5.0, "record_index": 1,
        "record": "fema-nearfield:NORTHR/RRS_032", "polarity": 1, "scale": "table", "repetition": 1}


@pytest.mark.parametrize("name", ["quick.toml", "paper-campaign.toml"])
def test_to_dict_is_json_and_reads_back(name: str) -> None:
    seq = load_sequence(EXAMPLES / name)
    data = seq.to_dict()
    text = json.dumps(data, allow_nan=False)
    assert json.loads(text) == data
    again = Sequence.from_dict(json.loads(text))
    assert again.to_dict() == data
    assert again.table == seq.table and again.bodies == seq.bodies and again.records[0].spec == seq.records[0].resolved
    assert data["schema"] == "shaketable-rig/sequence/1"
    assert data["bodies"][0]["body_id"] == 1


def test_a_bodys_measured_restitution_is_read_kept_and_given_to_the_emulator(tmp_path: Path) -> None:
    seq = load_sequence(write(tmp_path, BASE + "restitution = 0.85\n"))
    assert [b.restitution for b in seq.bodies] == [None, 0.85]
    data = seq.to_dict()
    assert "restitution" not in data["bodies"][0] and data["bodies"][1]["restitution"] == 0.85
    assert Sequence.from_dict(json.loads(json.dumps(data))).bodies == seq.bodies
    flags = specimen_flags(seq.bodies)
    assert "restitution" not in flags[1] and flags[3].endswith(";mu=0.8;mass=0.56;restitution=0.85")
    placed = parse_body(flags[3])
    assert placed.restitution == 0.85 and (placed.x, placed.y, placed.friction) == (0.0, 0.15, 0.8)


def test_a_bodys_centre_of_gravity_is_read_kept_and_given_to_the_emulator(tmp_path: Path) -> None:
    """Table V's centre of gravity comes with table5 = N (and a b_cg given beside it replaces the paper's: the block
    mounted the other way round); dimensions take b_cg, h_cg; the sequence keeps them, the emulator gets them."""
    text = BASE.replace("table5 = 4\n", "table5 = 1\n").replace("y = -0.15", "y = -0.25") + "b_cg = 0.026\n"
    seq = load_sequence(write(tmp_path, text))
    t5_1, b2 = (b.body for b in seq.bodies)
    assert t5_1 == TABLE_V[0] and (t5_1.b_cg, t5_1.h_cg) == (0.0515, 0.243)
    assert (b2.b_cg, b2.h_cg) == (0.026, None) and b2.cg == (0.026, 0.1)
    data = seq.to_dict()
    assert data["bodies"][0]["b_cg"] == 0.0515 and "h_cg" not in data["bodies"][1]
    assert Sequence.from_dict(json.loads(json.dumps(data))).bodies == seq.bodies
    flags = specimen_flags(seq.bodies)
    assert flags[1].endswith(";cg=0.0515,0.243") and flags[3].endswith(";cg=0.026,0.1")
    assert parse_body(flags[1]).body.cg == (0.0515, 0.243)
    mirrored = load_sequence(write(tmp_path, text.replace("table5 = 1\n", "table5 = 1\nb_cg = 0.0475\n")))
    assert mirrored.bodies[0].body.cg == (0.0475, 0.243) and mirrored.bodies[0].name == "T5-1"
    assert mirrored.bodies[0].body.alpha_plus == pytest.approx(TABLE_V[0].alpha_minus)


def test_a_body_stands_only_below_its_slenderness_towards_the_low_side(tmp_path: Path) -> None:
    """A plate tilted towards +x tips a block over its downhill corner at β = α+ = atan((b − b_cg)/h_cg)."""
    text = BASE.replace("mass = 0.56\n", "mass = 0.56\nb_cg = 0.04\n")  # 9 mm from its downhill corner: α+ = 5.1°
    seq = load_sequence(write(tmp_path, text.replace("angles_deg = [0, 5]", "angles_deg = [0, 5.5]")))
    problem = seq.bodies[1].standing_problem(5.5)
    assert problem is not None and "atan((b − b_cg)/h_cg), towards +x (downhill), = 5.14°" in problem
    assert seq.bodies[1].standing_problem(5.0) is None
    error = refused(tmp_path, text.replace("angles_deg = [0, 5]", "angles_deg = [0, 5.5]"), check=True)
    assert "body 2 (B" in str(error) and "cannot stand at β = 5.5°" in str(error)


def test_from_dict_errors_name_the_key_without_a_line() -> None:
    data = load_sequence(EXAMPLES / "quick.toml").to_dict()
    data["bodies"][1]["h"] = -1.0
    with pytest.raises(SequenceError) as caught:
        Sequence.from_dict(data, source="session.h5")
    assert str(caught.value) == "session.h5: bodies[2].h: expected a height from 0.001 m to 5 m, got -1.0"
    assert caught.value.line is None and caught.value.key == "bodies[2].h"


def test_key_lines_follow_arrays_of_tables_and_inline_values() -> None:
    text = ('a = [1,\n  { k = "x # y" },\n]\n[[t]]\nv = 1\n[[t]]\n"q.k" = """\n]\n"""\nw = 2\n[t.sub]\nz = 3\n')
    lines = key_lines(text)
    assert lines[("a", 1, "k")] == 2 and lines[("t", 1)] == 6 and lines[("t", 1, "w")] == 10
    assert lines[("t", 1, "sub", "z")] == 12 and lines[("t", 0, "v")] == 5 and lines[("t", 1, "q.k")] == 7
    assert dotted_path(("t", 1, "sub")) == "t[2].sub"


# ----- polarity ----------------------------------------------------------------------------------------------


def test_polarity_both_plays_each_record_as_recorded_then_negated(tmp_path: Path) -> None:
    seq = load_sequence(write(tmp_path, 'polarity = "both"\n' + BASE))
    assert [(e.spec, e.polarity) for e in seq.records] == [
        ("fema-farfield:KOBE/NIS000", 1), ("fema-farfield:KOBE/NIS000", -1),
        ("fema-nearfield:NORTHR/RRS_032", 1), ("fema-nearfield:NORTHR/RRS_032", -1)]
    assert len(seq.plan()) == 2 * 4
    # the label is the session's run `record`: the polarity is kept with every run, and splits off again
    labels = [run.record.label() for run in seq.plan()[:4]]
    assert labels[1] == "fema-farfield:KOBE/NIS000 (negated)"
    assert [record_of_label(label) for label in labels[:2]] == [("fema-farfield:KOBE/NIS000", 1),
                                                                ("fema-farfield:KOBE/NIS000", -1)]
    assert [run.to_dict()["polarity"] for run in seq.plan()[:4]] == [1, -1, 1, -1]
    # the negated record: its fall-line component × −1, the vertical and second horizontal as recorded
    as_recorded, negated = seq.motion(2), seq.motion(3)
    np.testing.assert_array_equal(negated.acc_h, -as_recorded.acc_h)
    assert negated.name.endswith(" (negated)") and negated.provenance["polarity"] == -1
    assert negated.provenance["sha256"] != as_recorded.provenance["sha256"]
    # its drive: the same scale factor inside the table's symmetric limits, surge mirrored
    runs = seq.plan()
    plus, minus = seq.prepare(runs[6]), seq.prepare(runs[7])
    assert minus.scale_factor == pytest.approx(plus.scale_factor)
    np.testing.assert_allclose(minus.poses[:, 0], -plus.poses[:, 0], atol=1e-12)
    # the session's copy reads back with the polarity of each entry
    again = Sequence.from_dict(json.loads(json.dumps(seq.to_dict())))
    assert [e.polarity for e in again.records] == [1, -1, 1, -1] and again.to_dict() == seq.to_dict()


def test_polarity_of_one_record_and_of_records_from(tmp_path: Path) -> None:
    text = BASE.replace('"fema-farfield:KOBE/NIS000",',
                        '{ record = "fema-farfield:KOBE/NIS000", polarity = "negated" },')
    seq = load_sequence(write(tmp_path, 'polarity = "both"\nrecords_from = { suite = "fema", strongest = 2, '
                                        'polarity = "as recorded" }\n' + text))
    assert [e.polarity for e in seq.records] == [-1, 1, -1, 1, 1]


@pytest.mark.parametrize(("text", "line", "message"), [
    ('polarity = "mirrored"\n', 1, "polarity: expected one of 'as recorded', 'negated', 'both'"),
    ('polarity = "both"\n', 6, "records[2]: fema-nearfield:NORTHR/RRS_032 [0.5-5.5 s] plays a compensated drive"),
])
def test_bad_polarity_is_refused_at_its_line(tmp_path: Path, text: str, line: int, message: str) -> None:
    base = BASE.replace('window_s = [0.5, 5.5] }', f'window_s = [0.5, 5.5], drive = "{tmp_path / "d.h5"}" }}')
    with pytest.raises(SequenceError, match=message.replace("[", r"\[").replace("]", r"\]")) as err:
        load_sequence(write(tmp_path, text + base))
    assert err.value.line == line


def test_rig_study_bodies_take_table_v_and_a_centre_of_gravity(tmp_path: Path) -> None:
    """``rig study --bodies``: Table V with its centres of gravity, or sizes each with an optional ;cg=BCG,HCG (its
    comma is not a new body); a saved study keeps them."""
    from analysis.body import TABLE_I, Body
    from analysis.study import study
    from rig.cli.study import parse_bodies
    from rig.records import load_records
    from rig.study_file import read_study, write_study
    from rig.study_summary import study_summary

    assert parse_bodies("table5") == list(TABLE_V) and parse_bodies("table5:1,5") == [TABLE_V[0], TABLE_V[4]]
    assert parse_bodies("0.099x0.493;cg=0.0515,0.243,0.2x1.0") == [Body(0.099, 0.493, b_cg=0.0515, h_cg=0.243),
                                                                  Body(0.2, 1.0)]
    assert parse_bodies("table1:2") == [TABLE_I[1]]
    res = study([TABLE_V[0], TABLE_I[0]], load_records("fema-farfield")[:1], np.radians([0.0]))
    saved = read_study(write_study(res, study_summary(res), tmp_path / "s.h5"))
    assert [(b.b, b.h, b.b_cg, b.h_cg) for b in saved.bodies] == [(0.099, 0.493, 0.0515, 0.243),
                                                                 (0.04, 0.2, None, None)]
