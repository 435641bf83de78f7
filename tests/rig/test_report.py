"""``rig report``: session and study reports from small real files, self-contained HTML, the response spectrum
against closed forms, and the page in headless Chromium (skipped when Debian's chromium is not installed).

The session file is written by the real `SessionLog` with the quick sequence's real prepared drives (the
"measurement" is the command seen by a plate-frame accelerometer, with noise); the ``analysis`` datasets are written
here in the layout agreed with ``rig analyze`` (`rig.report.data`); the study file by ``rig study``'s own writer
from a real small `analysis.study.study` run.
"""

from __future__ import annotations

import base64
import hashlib
import io
import json
import math
import re
import shutil
import subprocess
from html import unescape
from pathlib import Path

import h5py
import numpy as np
import pytest
import typer
from PIL import Image
from scipy import signal
from typer.testing import CliRunner

from analysis import TABLE_I
from analysis.body import G
from analysis.spectrum import (
    filter_coefficients,
    nigam_jennings,
    pseudo_acceleration_spectrum,
    relative_displacement,
    uniform,
)
from analysis.study import study
from rig.analyze.fig13 import Case, fig13_rows, to_array
from rig.cli import report as cli_report
from rig.records import load_records
from rig.report import ReportError, file_kind, write_report
from rig.sequence import load_sequence
from rig.session import SessionLog
from rig.study_file import write_study
from rig.study_summary import study_summary
from tests.helpers.console import CHROMIUM

ROOT = Path(__file__).resolve().parents[2]
A4_WIDTH_PX = 794  # 210 mm at 96 dpi
A4_HEIGHT_PX = 1123

# -- the response spectrum against closed forms ---------------------------------------------------------------


@pytest.mark.parametrize(("period", "damping", "forcing_period"), [(0.5, 0.05, 0.8), (0.2, 0.05, 0.15),
                                                                    (1.0, 0.02, 1.0), (2.0, 0.10, 0.7)])
def test_harmonic_steady_state_amplitude_matches_the_closed_form(period: float, damping: float,
                                                                 forcing_period: float) -> None:
    dt, a0 = 0.0002, 2.0  # the linear interpolation between samples lowers the amplitude by ~(Ω dt)²/12 < 1e-5
    w, omega = 2 * math.pi / period, 2 * math.pi / forcing_period
    t = np.arange(0.0, 30 * period / (2 * math.pi * damping) + 5 * forcing_period, dt)
    u = relative_displacement(a0 * np.sin(omega * t), dt, period, damping)
    tail = t > t[-1] - 5 * forcing_period  # transients decayed: 30 time constants 1/(ζω) before
    basis = np.column_stack([np.sin(omega * t[tail]), np.cos(omega * t[tail])])
    coeffs, *_ = np.linalg.lstsq(basis, u[tail], rcond=None)
    amplitude = math.hypot(*coeffs)
    expected = a0 / math.sqrt((w**2 - omega**2) ** 2 + (2 * damping * w * omega) ** 2)
    assert amplitude == pytest.approx(expected, rel=3e-5)
    assert np.max(np.abs(u[tail] - basis @ coeffs)) < 1e-4 * expected


@pytest.mark.parametrize(("period", "damping"), [(0.3, 0.05), (1.0, 0.05), (2.5, 0.0)])
def test_step_response_and_its_spectral_peak_match_the_closed_form(period: float, damping: float) -> None:
    dt, a0 = 1e-4, 3.0
    w = 2 * math.pi / period
    wd = w * math.sqrt(1 - damping**2)
    t = np.arange(0.0, 3 * period, dt)
    u = relative_displacement(np.full(t.size, a0), dt, period, damping)
    # the filter starts at rest with a = 0 one step before the first sample: a ramp over [−dt, 0], whose response
    # is the step response delayed by dt/2 to first order
    ts = t + dt / 2
    closed = -(a0 / w**2) * (1 - np.exp(-damping * w * ts) * (np.cos(wd * ts) + damping * w / wd * np.sin(wd * ts)))
    assert np.max(np.abs(u - closed)) < 1e-5 * a0 / w**2
    psa = pseudo_acceleration_spectrum(np.full(t.size, a0), dt, [period], damping)
    assert psa[0] == pytest.approx(a0 * (1 + math.exp(-damping * math.pi / math.sqrt(1 - damping**2))), rel=1e-5)


def test_the_recurrence_matches_scipy_first_order_hold_simulation() -> None:
    rng = np.random.default_rng(3)
    dt = 0.005
    a = np.concatenate([[0.0], rng.normal(size=1999)])  # starts at 0: the filter's "at rest" is then exact
    t = dt * np.arange(a.size)
    for period, damping in ((0.1, 0.05), (0.7, 0.05), (3.0, 0.2)):
        w = 2 * math.pi / period
        system = signal.StateSpace([[0, 1], [-(w**2), -2 * damping * w]], [[0], [-1]], [[1, 0]], [[0]])
        _, y, _ = signal.lsim(system, a, t, interp=True)
        u = relative_displacement(a, dt, period, damping)
        assert np.max(np.abs(u - y)) < 1e-8 * np.max(np.abs(y))
        # the filter is the one-step matrices written as a transfer function
        am, bm = nigam_jennings(period, dt, damping)
        x = np.zeros(2)
        for i in range(1, 50):
            x = am @ x + bm @ a[i - 1:i + 1]
        assert x[0] == pytest.approx(u[49], rel=1e-9, abs=1e-15)
        b, den = filter_coefficients(period, dt, damping)
        assert den[0] == 1.0 and b.shape == (3,)


def test_the_compiled_spectrum_equals_one_filter_per_period() -> None:
    rng = np.random.default_rng(5)
    acc, dt = rng.normal(size=3000), 0.002
    periods = np.geomspace(0.02, 5.0, 25)
    pad = np.concatenate([acc, np.zeros(math.ceil(periods.max() / dt) + 1)])
    expected = [(2 * math.pi / p) ** 2 * np.max(np.abs(relative_displacement(pad, dt, p))) for p in periods]
    assert pseudo_acceleration_spectrum(acc, dt, periods) == pytest.approx(expected, rel=1e-9)
    assert pseudo_acceleration_spectrum([], dt, periods).tolist() == [0.0] * periods.size
    with pytest.raises(ValueError, match="finite"):
        pseudo_acceleration_spectrum([0.0, np.nan], dt, periods)


def test_uniform_resamples_jittered_samples() -> None:
    t = np.arange(0, 1, 0.001)
    values, dt = uniform(t, np.sin(t))
    assert dt == pytest.approx(0.001) and values.size == t.size
    jitter = t + np.random.default_rng(0).uniform(-2e-4, 2e-4, t.size)
    values, dt = uniform(jitter, np.sin(jitter))
    assert dt == pytest.approx(0.001, rel=0.05)
    grid = jitter.min() + dt * np.arange(values.size)
    assert np.max(np.abs(values - np.sin(grid))) < 1e-6


# -- test files -------------------------------------------------------------------------------------------------

PRED = np.dtype([("body_id", "<i4"), ("model", "S16"), ("direction", "i1"), ("t_overturn", "<f8"),
                 ("theta_max", "<f8"), ("observed", "i1")])


def plate_force(acc_h: np.ndarray, beta: float) -> np.ndarray:
    """What a plate-frame accelerometer reads for a horizontal base acceleration [m/s²] at tilt β."""
    cb, sb = math.cos(beta), math.sin(beta)
    return np.column_stack([acc_h * cb - G * sb, np.zeros_like(acc_h), acc_h * sb + G * cb])


def make_session(path: Path, runs: int = 3, analysed: bool = True) -> Path:
    """A session of the quick sequence: ``runs`` completed runs with the real drives (the last one refused), 1 kHz
    plate accelerometer; with ``analysed`` the ``analysis`` datasets of ``rig analyze``."""
    sequence = load_sequence(ROOT / "examples" / "quick.toml")
    bodies = [b.to_dict() for b in sequence.bodies]
    rng = np.random.default_rng(1)
    with SessionLog.create(path, sequence.table.to_dict(), sequence.to_dict(), "test") as log:
        plan = sequence.plan()
        for k, planned in enumerate(plan[: runs - 1]):
            drive = sequence.prepare(planned)
            run = log.begin_run(planned.plan_index, record=planned.record.label(), scale_factor=drive.scale_factor,
                                angle_deg=planned.angle_deg, commanded=np.column_stack([drive.t, drive.poses]),
                                bodies=bodies, sensors=["0"],
                                attrs={"governing_axis": drive.governing.axis,
                                       "governing_quantity": drive.governing.quantity,
                                       "corner_frequency": drive.corner_frequency, "table_url": "emulator"})
            t = np.arange(-0.3, drive.t[-1] + 0.3, 0.001)
            acc = np.interp(t, drive.t, drive.accelerations[:, 0], left=0.0, right=0.0)
            run.append_accel("0", t, plate_force(acc, planned.angle) + rng.normal(0, 0.02, (t.size, 3)))
            if k == 0:
                run.add_detection(2.5, bodies[0]["body_id"], 1, "sensor")
                run.add_detection(3.1, bodies[1]["body_id"], -1, "sensor")
            run.end("completed", underruns=0, t_start_controller_ns=123)
        refused = plan[runs - 1]
        run = log.begin_run(refused.plan_index, record=refused.record.label(), scale_factor=float("nan"),
                            angle_deg=refused.angle_deg, commanded=np.zeros((0, 7)), bodies=bodies, sensors=["0"],
                            attrs={"reason": "drive leaves the table"})
        run.end("refused", reason="drive leaves the table")
    if analysed:
        with h5py.File(path, "r+", locking=False) as h5:
            for k, name in enumerate(sorted(h5["runs"])[: runs - 1]):
                observed = {bodies[0]["body_id"]: 1, bodies[1]["body_id"]: -1} if k == 0 else {}
                rows = [(b["body_id"], model, observed.get(b["body_id"], 0), 2.4 if observed else np.nan, 0.3,
                         observed.get(b["body_id"], 0)) for b in bodies for model in (b"rocking", b"general")]
                h5["runs"][name].create_group("analysis").create_dataset("predictions", data=np.array(rows, PRED))
            cases = []
            for angle, low in ((0.0, 1), (4.0, 2)):  # 3 runs, 2 overturns, `low` of them towards the low side
                for body in bodies:
                    for model in ("rocking", "general"):
                        directions = [1] * low + [-1] * (2 - low) + [0]
                        cases += [Case(angle, int(body["body_id"]), model, d, d, f"record {k}")
                                  for k, d in enumerate(directions)]
            group = h5.create_group("analysis")
            group.create_dataset("fig13", data=to_array(fig13_rows(cases)))
            group.attrs["margin"] = 0.05
            group.attrs["max_difference_rocking"] = 0.0
            group.attrs["max_difference_general"] = 0.01
    return path


def make_study(path: Path) -> Path:
    """A real small study (5 Table I bodies, 12 FEMA far-field records, both signs, 0–7°) saved by ``rig study``'s
    writer (``rig.study_file.write_study``)."""
    bodies = [TABLE_I[i] for i in (0, 3, 5, 8, 11)]
    res = study(bodies, load_records("fema-farfield")[:12], np.radians([0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 7.0]))
    return write_study(res, study_summary(res), path)


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("report")
    out = {"session": make_session(d / "session.h5"), "bare": make_session(d / "bare.h5", runs=2, analysed=False),
           "study": make_study(d / "study.h5")}
    for kind in ("session", "bare", "study"):
        out[f"{kind}_html"] = write_report(out[kind], d / f"{kind}.html").output
    return out


# -- the reports ------------------------------------------------------------------------------------------------

IMG = re.compile(r'<img [^>]*src="([^"]*)"')


def assert_self_contained(html: str) -> list[bytes]:
    """No reference leaves the file; returns the embedded PNGs."""
    assert not re.search(r"https?:", html), "an http(s) reference"
    assert "<script" not in html and "<link" not in html and "@import" not in html and "url(" not in html
    for attr in re.findall(r'\s(?:src|href)="([^"]*)"', html):
        assert attr.startswith(("data:image/png;base64,", "#")), attr[:60]
    pngs = [base64.b64decode(src.removeprefix("data:image/png;base64,")) for src in IMG.findall(html)]
    for png in pngs:
        image = Image.open(io.BytesIO(png)).convert("L")
        assert image.width >= 600 and image.height >= 200
        assert np.asarray(image).std() > 10, "a blank figure"
    return pngs


def test_session_report(files: dict[str, Path]) -> None:
    html = files["session_html"].read_text()
    pngs = assert_self_contained(html)
    # two runs with samples (each: acceleration and spectrum, tracking), Fig. 2 of the bodies, Fig. 13
    assert len(pngs) == 6 and html.count("<figure>") == 6
    assert "Analysis against experiment (Fig. 13)" in html and "not analysed yet" not in html.lower()
    for text in ("fema-nearfield:NORTHR/RRS_032", "governing limit", "Records and scale factors", "refused",
                 "drive leaves the table", "Detections", "low side (+1)", "high side (−1)", "rocking", "general",
                 "Motion limits", "A<sub>min+</sub>", "5 % damped pseudo-acceleration", "−g sin β",
                 "not resolved with 3 runs (about", "±5 pp", "1.00 (0/0); 1.00 (0/0)", "1/2: 50 ["):
        assert text in html, text
    assert html.count('<section class="run"') == 3


def test_session_report_scale_factors_and_peaks_are_those_of_the_file(files: dict[str, Path]) -> None:
    html = files["session_html"].read_text()
    with h5py.File(files["session"], "r", swmr=True) as h5:
        run = h5["runs/0001"]
        scale = float(run.attrs["scale_factor"])
        axis, quantity = run.attrs["governing_axis"], run.attrs["governing_quantity"]
    assert f"{scale:.3f} ({axis} {quantity})" in html
    # the measured peak (noise σ 0.02 m/s² on the command) is close to the commanded one
    row = re.search(r'href="#run-0001">0001</a></td>(.*?)</tr>', html).group(1)
    cells = re.findall(r"<td[^>]*>(.*?)</td>", row)
    cmd, meas = float(cells[5]), float(cells[6])
    assert meas == pytest.approx(cmd, abs=0.15)


def test_unanalysed_session_says_so(files: dict[str, Path]) -> None:
    html = files["bare_html"].read_text()
    assert "Not analysed yet (rig analyze)" in html
    assert len(assert_self_contained(html)) == 3  # one run with samples (two figures), Fig. 2


def test_session_analysed_by_rig_analyze(files: dict[str, Path], tmp_path: Path) -> None:
    """The layout `rig analyze` really writes is the one the report reads."""
    from rig.analyze import analyze_session

    session = tmp_path / "analysed.h5"
    shutil.copy(files["bare"], session)
    analyze_session(session, models=("rocking",))
    html = write_report(session, tmp_path / "analysed.html").output.read_text()
    assert "Not analysed yet" not in html and "Fig. 13 data" in html
    assert "Analysis (rig analyze): predicted against observed" in html
    assert "plastic (no bounce, the paper&#x27;s)" in html or "plastic (no bounce, the paper's)" in html
    assert len(assert_self_contained(html)) == 4  # the run's two, Fig. 2, Fig. 13
    analyze_session(session, models=("rocking",), restitution="housner")
    html = write_report(session, tmp_path / "housner.html").output.read_text()
    assert "Housner" in html and "1 − 1.5 sin²α" in html and "plastic (no bounce" not in html


def test_study_report(files: dict[str, Path]) -> None:
    html = files["study_html"].read_text()
    assert len(assert_self_contained(html)) == 3  # Fig. 2, average COR with Eq. 11, per body with Eqs. 11 and 13
    for text in ("Table II equivalent", "Table III equivalent", "Eq. 11 fitted", "Eq. 13 (SCOR)", "Fitted "
                 "coefficients", "95 % confidence interval", "max diff. GCOR [%]", "Outcomes per body", "0.048"):
        assert text in html, text
    with h5py.File(files["study"], "r") as h5:
        c1 = float(h5["fits/gcor"].attrs["c1"])
    assert f"{c1:.4f}" in html


def test_kind_is_read_from_the_schema_attribute(files: dict[str, Path], tmp_path: Path) -> None:
    assert file_kind(files["session"]) == "session" and file_kind(files["study"]) == "study"
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as h5:
        h5.attrs["schema"] = "something/else"
    with pytest.raises(ReportError, match="schema attribute"):
        write_report(other, tmp_path / "x.html")
    (tmp_path / "text.h5").write_text("not hdf5")
    with pytest.raises(ReportError, match="not an HDF5 file"):
        write_report(tmp_path / "text.h5", tmp_path / "y.html")


def test_the_input_is_never_overwritten_and_the_output_is_replaced_atomically(files: dict[str, Path],
                                                                               tmp_path: Path) -> None:
    study_file = files["study"]
    digest = hashlib.sha256(study_file.read_bytes()).hexdigest()
    with pytest.raises(ReportError, match="input"):
        write_report(study_file, study_file)
    link = tmp_path / "link.html"
    link.symlink_to(study_file)
    with pytest.raises(ReportError, match="input"):
        write_report(study_file, link)
    assert hashlib.sha256(study_file.read_bytes()).hexdigest() == digest
    out = tmp_path / "r.html"
    out.write_text("old")
    result = write_report(study_file, out)
    assert out.read_text().startswith("<!DOCTYPE html>") and result.bytes == out.stat().st_size
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.html", "r.html"]


def test_cli_report_json(files: dict[str, Path], tmp_path: Path) -> None:
    app = typer.Typer()

    @app.callback()
    def main() -> None:
        """Test root."""

    cli_report.register(app)
    out = tmp_path / "s.html"
    result = CliRunner().invoke(app, ["report", str(files["study"]), "-o", str(out), "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["kind"] == "study" and summary["figures"] == 3 and Path(summary["output"]) == out
    bad = CliRunner().invoke(app, ["report", str(files["study"]), "-o", str(files["study"]), "--json"])
    assert bad.exit_code == 2 and "never written over an input" in bad.output


# -- the page in a browser --------------------------------------------------------------------------------------

PROBE = """<script>
window.__errors = [];
window.addEventListener("error", e => window.__errors.push(String(e.message || (e.target && e.target.src))), true);
window.addEventListener("load", () => {
  const de = document.documentElement;
  const imgs = Array.from(document.images).map(i => { const r = i.getBoundingClientRect();
    return {x: r.left + scrollX, y: r.top + scrollY, w: r.width, h: r.height, nw: i.naturalWidth,
            ok: i.complete && i.naturalWidth > 0}; });
  const pre = document.createElement("pre"); pre.id = "probe";
  pre.textContent = JSON.stringify({scrollWidth: de.scrollWidth, clientWidth: de.clientWidth,
                                    scrollHeight: de.scrollHeight, imgs: imgs, errors: window.__errors});
  document.body.appendChild(pre);
});
</script>"""


def chromium(args: list[str], profile: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(CHROMIUM), "--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                           "--force-device-scale-factor=1", "--no-first-run", "--no-default-browser-check",
                           "--disable-extensions", "--disable-background-networking", f"--user-data-dir={profile}",
                           *args], capture_output=True, text=True, timeout=120)


def console_errors(stderr: str) -> list[str]:
    """Console messages and failed loads Chromium logged on stderr (``--enable-logging=stderr``)."""
    return [line for line in stderr.splitlines()
            if "CONSOLE" in line or "Failed to load resource" in line or "Uncaught" in line]


def blank(image: Image.Image, box: tuple[int, int, int, int]) -> bool:
    """Whether the screenshot's pixels in ``box`` (left, top, right, bottom) are (almost) all one colour."""
    region = np.asarray(image.crop(box).convert("L"), dtype=float)
    return region.size == 0 or region.std() < 8 or np.mean(region < 200) < 0.01


def test_the_blank_check_tells_an_empty_region_from_a_figure() -> None:
    white = Image.new("RGB", (100, 100), "white")
    assert blank(white, (0, 0, 100, 100))
    drawn = white.copy()
    drawn.paste((0, 0, 0), (0, 50, 100, 53))
    drawn.paste((40, 90, 200), (20, 0, 22, 100))
    assert not blank(drawn, (0, 0, 100, 100))


def browser_check(html_path: Path, work: Path) -> dict:
    """Open the report in headless Chromium: a probe copy gives the layout, the original is screenshot at A4
    width with console logging; returns the probe's findings."""
    probe_copy = work / f"probe-{html_path.name}"
    probe_copy.write_text(html_path.read_text().replace("</head>", PROBE + "</head>", 1))
    dom = chromium(["--virtual-time-budget=10000", f"--window-size={A4_WIDTH_PX},{A4_HEIGHT_PX}", "--dump-dom",
                    probe_copy.as_uri()], work / "profile-dom")
    found = re.search(r'<pre id="probe">(.*?)</pre>', dom.stdout, re.S)
    assert found, dom.stderr[-2000:]
    probe = json.loads(unescape(found.group(1)))
    height = min(int(probe["scrollHeight"]), 16000)
    shot = work / f"{html_path.stem}.png"
    run = chromium(["--enable-logging=stderr", "--v=0", f"--window-size={A4_WIDTH_PX},{height}",
                    f"--screenshot={shot}", html_path.as_uri()], work / "profile-shot")
    assert shot.is_file(), run.stderr[-2000:]
    probe["console"] = console_errors(run.stderr)
    probe["screenshot"] = Image.open(shot).convert("RGB")
    return probe


@pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian's chromium is not installed (apt-get install chromium)")
@pytest.mark.integration
def test_console_errors_are_caught_on_a_page_that_has_them(tmp_path: Path) -> None:
    bad = tmp_path / "bad.html"
    bad.write_text('<!DOCTYPE html><html><body><p>x</p><img src="missing.png">'
                   '<script>console.error("probe-error")</script></body></html>')
    run = chromium(["--enable-logging=stderr", "--v=0", f"--window-size={A4_WIDTH_PX},200",
                    f"--screenshot={tmp_path / 'bad.png'}", bad.as_uri()], tmp_path / "profile")
    assert any("probe-error" in line for line in console_errors(run.stderr)), run.stderr[-2000:]


@pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian's chromium is not installed (apt-get install chromium)")
@pytest.mark.parametrize("kind", ["session", "study"])
@pytest.mark.integration
def test_the_report_in_headless_chromium(files: dict[str, Path], kind: str, tmp_path: Path) -> None:
    html_path = files[f"{kind}_html"]
    n_images = len(IMG.findall(html_path.read_text()))
    probe = browser_check(html_path, tmp_path)
    assert probe["errors"] == [] and probe["console"] == [], (probe["errors"], probe["console"])
    assert probe["clientWidth"] == A4_WIDTH_PX and probe["scrollWidth"] <= A4_WIDTH_PX  # fits A4 width
    assert len(probe["imgs"]) == n_images > 0
    shot: Image.Image = probe["screenshot"]
    assert shot.width == A4_WIDTH_PX
    for img in probe["imgs"]:
        assert img["ok"] and img["nw"] >= 600, img
        assert 600 <= img["w"] <= A4_WIDTH_PX and img["h"] >= 150, img  # 100 % of a body ≤ 180 mm wide
        box = (int(img["x"]), int(img["y"]), int(img["x"] + img["w"]), int(img["y"] + img["h"]))
        assert box[3] <= shot.height, (box, shot.height)
        assert not blank(shot, box), f"figure at {box} is blank in the screenshot"
