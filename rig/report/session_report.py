"""The report of a session file: the rig and the sequence, a table of the runs, the records' scale factors, the
Fig. 13 comparison (or "not analysed yet"), and per run its record, scale factor and governing limit, commanded
against measured horizontal acceleration with their response spectra, how the table followed the drive (the
fall-line acceleration error, the plate pose, the legs' strokes against their limits: `rig.report.tracking`),
detections, the analysis' predictions, and the run's faults and events (what degraded it).

**Accelerations shown.** Commanded: the second derivative of the commanded surge (central differences of
``commanded``). Measured: the plate-frame specific force (f_x, f_z) of the accelerometers rotated back to the
horizontal at the run's nominal tilt β, ``a_h = f_x cos β + f_z sin β`` — the plate-frame reading with its static
tilt component −g sin β removed (exactly so at rest: f = (−g sin β, 0, g cos β) gives 0); the mean of the sensors
when there are several (on the first one's time grid), as ``rig analyze`` takes them.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.body import G
from analysis.spectrum import DAMPING, DEFAULT_PERIODS, pseudo_acceleration_spectrum, uniform
from rig.analyze.fig13 import side_by_side, split_label, verdict_words
from rig.analyze.store import fitted_restitution

from . import figures
from .compensation_report import compensation_section
from .data import RunData, SessionData, iter_runs, read_header
from .html import esc, figure, key_values, num, table
from .sensors import sensors_table
from .tracking import fall_line_error, leg_strokes

Progress = Callable[[int, int], None]

_DIRECTION = {1: "low side (+1)", -1: "high side (−1)", 0: "none (0)"}
MEASURED_CAPTION = ("measured: the plate-frame specific force (f<sub>x</sub>, f<sub>z</sub>) rotated to the "
                    "horizontal at the nominal tilt β, a<sub>h</sub> = f<sub>x</sub> cos β + f<sub>z</sub> sin β, "
                    "i.e. f<sub>x</sub> with its static tilt component −g sin β removed")


@dataclass
class RunSummary:
    """What the runs table says of a run, gathered while its section is drawn."""

    name: str
    record: str
    angle_deg: float
    scale_factor: float | None
    governing: str
    status: str
    peak_commanded: float | None
    peak_measured: float | None
    error_rms: float | None
    error_peak: float | None
    overturns: str


def commanded_acceleration(commanded: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t [s], surge acceleration [m/s²]): the commanded surge differentiated twice (central differences)."""
    if commanded.shape[0] < 3:
        return np.zeros(0), np.zeros(0)
    t, x = commanded[:, 0], commanded[:, 1]
    return t, np.gradient(np.gradient(x, t), t)


def measured_horizontal(accel: dict[str, np.ndarray], beta: float) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(t [s], horizontal acceleration [m/s²], sensors used): ``f_x cos β + f_z sin β`` (module docstring),
    averaged over the sensors with samples on the first one's time grid."""
    used = [s for s, a in accel.items() if a.ndim == 2 and a.shape[0] >= 2 and a.shape[1] >= 4]
    if not used:
        return np.zeros(0), np.zeros(0), []
    first = accel[used[0]]
    ok = np.isfinite(first).all(axis=1)
    t = first[ok, 0]
    total = np.zeros_like(t)
    cb, sb = math.cos(beta), math.sin(beta)
    for sensor in used:
        a = accel[sensor]
        a = a[np.isfinite(a).all(axis=1)]
        a = a[np.argsort(a[:, 0], kind="stable")]
        h = a[:, 1] * cb + a[:, 3] * sb
        total += h if a.shape[0] == t.size and np.array_equal(a[:, 0], t) else np.interp(t, a[:, 0], h)
    return t, total / len(used), used


def _spectrum(t: np.ndarray, a: np.ndarray) -> np.ndarray | None:
    values, dt = uniform(t, a)
    return pseudo_acceleration_spectrum(values, dt, DEFAULT_PERIODS) if values.size >= 2 else None


def _peak(a: np.ndarray) -> float | None:
    return float(np.max(np.abs(a))) if a.size else None


def _body_names(bodies: Sequence[dict[str, Any]]) -> dict[int, str]:
    return {int(b["body_id"]): str(b.get("name") or "") for b in bodies if "body_id" in b}


def _governing(attrs: dict[str, Any]) -> str:
    axis, quantity = attrs.get("governing_axis"), attrs.get("governing_quantity")
    return f"{axis} {quantity}" if axis and quantity else "–"


def _direction(value: Any) -> str:
    try:
        return _DIRECTION.get(int(value), str(value))
    except (TypeError, ValueError):
        return str(value)


def _predictions_table(run: RunData, names: dict[int, str]) -> str:
    preds = run.predictions or []
    models = sorted({str(p["model"]) for p in preds})
    by_body: dict[int, dict[str, Any]] = {}
    for p in preds:
        by_body.setdefault(int(p["body_id"]), {"observed": p.get("observed")})[str(p["model"])] = p
    rows = []
    for body_id in sorted(by_body):
        row = by_body[body_id]
        cells = [f"{body_id} {names.get(body_id, '')}".strip(), _direction(row["observed"])]
        for model in models:
            predicted = row.get(model)
            if predicted is None:
                cells.append("–")
                continue
            when = f", t = {num(predicted['t_overturn'], '.2f')} s" if int(predicted["direction"]) != 0 else ""
            cells.append(f"{_direction(predicted['direction'])}{when}, θmax = {num(predicted['theta_max'], '.3f')} rad")
        rows.append(cells)
    return table(["body", "observed", *[esc(m) for m in models]], rows, left=2 + len(models),
                 caption="Analysis (rig analyze): predicted against observed overturn direction")


def run_section(run: RunData, names: dict[int, str], drawer: figures.RunFigure | None = None,
                rig_config: dict[str, Any] | None = None, tracker: figures.TrackingFigure | None = None
                ) -> tuple[str, RunSummary]:
    """One run's section (HTML) and its line of the runs table; ``drawer`` and ``tracker``: the figures to redraw
    (new ones if None); ``rig_config``: the session's rig (the legs' geometry and stroke limits; default: the
    default rig)."""
    beta = math.radians(run.angle_deg)
    t_cmd, a_cmd = commanded_acceleration(run.commanded)
    t_meas, a_meas, sensors = measured_horizontal(run.accel, beta)
    psa_cmd, psa_meas = _spectrum(t_cmd, a_cmd), _spectrum(t_meas, a_meas)
    names = {**names, **_body_names(run.bodies)}
    marks = [figures.Mark(float(d["t"]), f"{d['body_id']}{'↓' if int(d['direction']) > 0 else '↑'}")
             for d in run.detections if d.get("t") is not None and np.isfinite(d["t"])]
    title = f"Run {esc(run.name)} · {esc(run.record)} · β = {run.angle_deg:g}°"
    attrs = run.attrs
    facts = [f"status <b>{esc(run.status)}</b>", f"scale factor <b>{num(run.scale_factor, '.3f')}</b>",
             f"governing limit <b>{esc(_governing(attrs))}</b>"]
    if attrs.get("corner_frequency") is not None:
        facts.append(f"high-pass corner {num(attrs['corner_frequency'], '.3g')} Hz")
    if attrs.get("underruns") is not None:
        facts.append(f"underruns {esc(attrs['underruns'])}")
    if attrs.get("reason"):
        facts.append(f'<span class="warn">{esc(attrs["reason"])}</span>')
    facts.extend(f'<span class="warn">{esc(note)}</span>' for note in run.checksum_notes)
    facts.append(f"{run.commanded.shape[0]} commanded samples, {t_meas.size} measured "
                 f"({esc(', '.join(sensors)) or 'no sensor'})")
    parts = [f'<section class="run" id="run-{esc(run.name)}"><h3>{title}</h3>',
             f'<p class="small">{" · ".join(facts)}</p>']
    if t_cmd.size or t_meas.size:
        drawer = drawer or figures.RunFigure(DEFAULT_PERIODS)
        png = drawer.render(t_cmd, a_cmd, t_meas, a_meas, psa_cmd, psa_meas, marks)
        parts.append(figure(png, (
            f"Run {esc(run.name)}: (a) commanded (second derivative of the commanded surge) and measured "
            f"horizontal acceleration [m/s²]; {MEASURED_CAPTION}. Dotted lines: detections (body id, ↓ towards "
            f"the low side, ↑ the high side). (b) their {DAMPING * 100:g} % damped pseudo-acceleration spectra "
            f"[m/s²]."), alt=f"run {run.name} acceleration and response spectrum"))
    else:
        parts.append('<p class="note">No commanded or measured samples in this run.</p>')
    error = fall_line_error(run.commanded, run.accel, beta)
    legs = leg_strokes(run.pose, rig_config or {})
    if error is not None or legs is not None or run.pose.shape[0] or run.following_error.shape[0]:
        parts.append(_tracking(run, error, legs, tracker or figures.TrackingFigure()))
    if run.detections:
        parts.append(table(["t [s]", "body", "direction", "source"], [
            [num(d.get("t"), ".3f"), f"{d['body_id']} {names.get(int(d['body_id']), '')}".strip(),
             _direction(d["direction"]), d.get("source", "")] for d in run.detections],
            caption="Detections", left=4))
    else:
        parts.append('<p class="small">No overturn detected.</p>')
    if run.predictions:
        parts.append(_predictions_table(run, names))
    if run.faults:
        parts.append(table(["t [s]", "fault", "detail"],
                           [[num(f.get("t"), ".3f"), f.get("name", ""), f.get("detail", "")] for f in run.faults],
                           caption="Faults the table reported", left=3))
    events = run_events(run)
    if events:
        parts.append(table(["t [s]", "event"], [[num(t, ".3f"), text] for t, text in events],
                           caption="Events (degraded states, control requests; t – when not on the run's clock)",
                           left=2, wrap={1}))
    parts.append("</section>")
    overturns = " ".join(f"{d['body_id']}:{int(d['direction']):+d}" for d in run.detections) or "–"
    summary = RunSummary(run.name, run.record, run.angle_deg, run.scale_factor, _governing(attrs), run.status,
                         _peak(a_cmd), _peak(a_meas), None if error is None else error.rms,
                         None if error is None else error.peak, overturns)
    return "\n".join(parts), summary


def run_events(run: RunData) -> list[tuple[float | None, str]]:
    """The run's events: its ``events`` dataset (t [s], text), then those of an ``events`` run attribute (a JSON
    list of texts or of objects with ``t`` and ``text``: the degraded-state events a run may carry)."""
    rows: list[tuple[float | None, str]] = [(e.get("t"), str(e.get("text", ""))) for e in run.events]
    extra = run.attrs.get("events")
    if isinstance(extra, str):
        try:
            extra = json.loads(extra)
        except ValueError:
            extra = [extra]
    for item in extra if isinstance(extra, list) else []:
        if isinstance(item, dict):
            rows.append((item.get("t"), str(item.get("text") or item.get("event") or item)))
        else:
            rows.append((None, str(item)))
    return rows


def _tracking(run: RunData, error: Any, legs: Any, tracker: figures.TrackingFigure) -> str:
    """The run's tracking figure and the figures a table engineer looks for first (HTML)."""
    facts = []
    if error is not None:
        facts.append(f"fall-line error RMS <b>{error.rms:.3g} m/s²</b> ({num(error.rms_percent, '.1f')} % of the "
                     f"commanded RMS), peak <b>{error.peak:.3g} m/s²</b>")
    if legs is not None:
        leg, limit = legs.closest
        facts.append(f"closest to a stroke limit: leg {leg}, {1e3 * legs.margin:.0f} mm from {limit} "
                     f"({legs.leg_min:g}–{legs.leg_max:g} m)")
    if run.following_error.shape[0]:
        peaks = np.abs(run.following_error[:, 1:7]).max(axis=0) * 1e3
        facts.append("peak following error per leg 1–6 [mm]: " + " ".join(f"{peak:.2f}" for peak in peaks))
    png = tracker.render(None if error is None else (error.t, error.error, error.rms, error.peak),
                         None if legs is None else (legs.t, legs.lengths, legs.leg_min, legs.leg_max),
                         run.pose, run.commanded)
    caption = (f"Run {esc(run.name)}, how the table followed the drive: (c) measured − commanded fall-line "
               "acceleration [m/s²] (plate x, +downhill, gravity excluded; both low-passed at 50 Hz); (d) the legs' "
               "lengths [m] from the measured pose, stroke limits dashed; (e) plate translations [mm] and "
               "(f) rotations [°], measured from the controller's status, commanded thin and dark.")
    return (f'<p class="small">{" · ".join(facts)}</p>' if facts else "") + figure(
        png, caption, alt=f"run {run.name} tracking error, legs and pose")


def _runs_table(rows: list[RunSummary]) -> str:
    return table(
        ["run", "record", "β [°]", "scale", "governing limit", "status", "peak cmd [m/s²]", "peak meas [m/s²]",
         "fall-line error RMS / peak [m/s²]", "overturns body:dir"],
        [[f'<a href="#run-{esc(r.name)}">{esc(r.name)}</a>', esc(r.record), num(r.angle_deg, "g"),
          num(r.scale_factor, ".3f"), esc(r.governing), esc(r.status), num(r.peak_commanded, ".2f"),
          num(r.peak_measured, ".2f"), f"{num(r.error_rms, '.3g')} / {num(r.error_peak, '.3g')}",
          esc(r.overturns)] for r in rows],
        caption="Runs", left=2, wrap={1}, raw=True)


def _scale_table(header: SessionData) -> str:
    """The paper's Table VI: each record's scale factor (and governing limit) per plate angle."""
    angles = sorted({float(r["angle_deg"]) for r in header.runs if r.get("angle_deg") is not None})
    cells: dict[str, dict[float, set[str]]] = {}
    for r in header.runs:
        scale = r.get("scale_factor")
        if scale is None or not np.isfinite(scale):
            continue
        text = f"{scale:.3f} ({_governing(r.get('attrs', {}))})"
        cells.setdefault(str(r["record"]), {}).setdefault(float(r["angle_deg"]), set()).add(text)
    rows = [[rec, *["; ".join(sorted(cells[rec].get(a, set()))) or "–" for a in angles]] for rec in cells]
    return table(["record", *[f"β = {a:g}°" for a in angles]], rows, left=1 + len(angles), wrap={0},
                 caption="Records and scale factors (governing limit) per plate angle (the paper's Table VI)")


def _rig_section(header: SessionData) -> str:
    cfg = header.rig_config or (header.sequence.get("rig") if isinstance(header.sequence, dict) else {}) or {}
    parts = ["<h2>Rig</h2>"]
    limits = cfg.get("limits", {}) if isinstance(cfg, dict) else {}
    rate = (cfg.get("table", {}) or {}).get("controller_rate_hz") if isinstance(cfg, dict) else None
    urls = sorted({str(r.get("attrs", {}).get("table_url")) for r in header.runs
                   if r.get("attrs", {}).get("table_url")})
    parts.append(key_values([("controller rate", f"{num(rate, 'g')} Hz"), ("table", ", ".join(urls) or "–"),
                             ("software version", header.software_version)]))
    axes = [(name, lim) for name, lim in limits.items() if name != "tilt" and isinstance(lim, dict)]
    if axes:
        parts.append(table(
            ["axis", "displacement [m]", "velocity [m/s]", "acceleration [m/s²]", "acceleration [g]"],
            [[name, num(lim.get("displacement_m")), num(lim.get("velocity_m_s")), num(lim.get("acceleration_m_s2")),
              num(lim.get("acceleration_m_s2"), ".3g", 1 / G)] for name, lim in axes],
            caption="Motion limits (the paper's Table IV)", left=1))
    tilt = limits.get("tilt") if isinstance(limits, dict) else None
    if isinstance(tilt, dict):
        parts.append(key_values([
            ("tilt limit", f"{num(tilt.get('angle_rad'), '.3g', 180 / math.pi)}° at "
                           f"{num(tilt.get('rate_rad_s'), '.3g', 180 / math.pi)}°/s")]))
    parts.append(sensors_table(cfg if isinstance(cfg, dict) else {}, header.runs))
    return "\n".join(parts)


def _sequence_section(header: SessionData, body_rows: list[dict[str, Any]]) -> str:
    seq = header.sequence or {}
    parts = ["<h2>Sequence</h2>"]
    drive = seq.get("drive", {}) or {}
    operator = seq.get("operator", {}) or {}
    parts.append(key_values([
        ("name", seq.get("name")), ("description", seq.get("description")), ("source", seq.get("source")),
        ("angles", ", ".join(f"{a:g}°" for a in seq.get("angles_deg", [])) or None),
        ("repetitions", seq.get("repetitions")),
        ("drive", f"settle {num(drive.get('settle_s'), 'g')} s, high-pass corner "
                  + (f"{num(drive['corner_hz'], 'g')} Hz" if drive.get("corner_hz") is not None else "automatic")),
        ("operator", f"confirm before each run: {operator.get('confirm_before_run', '–')}, "
                     f"ask detections: {operator.get('ask_detections', '–')}"),
    ]))
    # a record is a table of the sequence file's keys, or (the file's short form) just its name
    recs = [r if isinstance(r, dict) else {"record": r} for r in seq.get("records", []) or []]
    if recs:
        parts.append(table(["#", "record", "scale", "window [s]", "corner [Hz]"], [
            [i + 1, r.get("record"), r.get("scale"), "–" if not r.get("window_s") else
             f"{r['window_s'][0]:g}–{r['window_s'][1]:g}", num(r.get("corner_hz"), "g")]
            for i, r in enumerate(recs)], caption="Records", left=2, wrap={1}))
    if body_rows:
        angles = [float(a) for a in seq.get("angles_deg", [])][:6]
        head = ["id", "name", "b [m]", "h [m]", "depth [m]", "mass [kg]", "x [m]", "y [m]", "α [°]"]
        head += [f"A<sub>min+</sub>/A<sub>min−</sub> at {a:g}° [g]" for a in angles]
        rows = []
        for b in body_rows:
            alpha = math.atan2(float(b["b"]), float(b["h"]))
            rows.append([esc(b.get("body_id")), esc(b.get("name", "")), num(b.get("b")), num(b.get("h")),
                         num(b.get("depth")), num(b.get("mass")), num(b.get("x")), num(b.get("y")),
                         f"{math.degrees(alpha):.1f}", *[
                             f"{math.tan(alpha - math.radians(a)):.3f} / {math.tan(alpha + math.radians(a)):.3f}"
                             for a in angles]])
        parts.append(table(head, rows, left=2, raw=True, caption=(
            "Bodies on the plate, with Eq. 1's accelerations that start rocking towards the low side "
            "(A<sub>min+</sub> = g tan(α − β)) and the high side (A<sub>min−</sub> = g tan(α + β))")))
        aspects = sorted({round(float(b["b"]) / float(b["h"]), 4) for b in body_rows})
        labels = [(x, "b/h = " + f"{x:.3g} (" + ", ".join(
            str(b.get("body_id")) for b in body_rows if round(float(b["b"]) / float(b["h"]), 4) == x) + ")")
            for x in aspects]
        top = max([7.0, *[float(a) + 1 for a in seq.get("angles_deg", [])]])
        png = figures.thresholds_figure(labels, top, [float(a) for a in seq.get("angles_deg", [])])
        parts.append(figure(png, (
            "Eq. 1 (the paper's Fig. 2) for the bodies on the plate: the horizontal acceleration [g] that starts "
            "rocking towards the low side (A<sub>min+</sub>, solid) and the high side (A<sub>min−</sub>, dashed) "
            "against the plate inclination β [°], no vertical acceleration; body ids in brackets; dotted: the "
            "sequence's angles."), alt="Eq. 1 thresholds against angle"))
    return "\n".join(parts)


def _impact_model(attrs: dict[str, Any]) -> list[tuple[str, str]]:
    """The models' impact rule as `rig analyze` used it, and each body's fitted restitution with ``fit``."""
    rule = str(attrs.get("restitution", "0.0"))
    named = {"housner": "Housner's restitution 1 − 1.5 sin²α", "fit": "restitution fitted per body from the "
             "measured tilts (ratio of rates across each impact)",
             "all": "plastic (the paper's), Housner's 1 − 1.5 sin²α and fitted per body from the measured tilts, "
                    "side by side (model:plastic, model:housner, model:fit)"}
    try:
        text = named.get(rule) or ("plastic (no bounce, the paper's)" if float(rule) == 0.0
                                   else f"restitution {float(rule):g}")
    except ValueError:
        text = rule
    return [("impact model", text)] + [(f"restitution, body {body.body_id}", body.label())
                                       for body in fitted_restitution(attrs)]


def _fig13_section(header: SessionData, names: dict[int, str]) -> str:
    parts = ["<h2>Analysis against experiment (Fig. 13)</h2>"]
    rows = header.fig13
    if not rows:
        parts.append('<p class="warn">Not analysed yet (rig analyze): run <code>rig analyze SESSION.h5</code> '
                     "to add the models' predictions on the measured plate motion and this comparison.</p>")
        return "\n".join(parts)
    models = sorted({str(r["model"]) for r in rows})
    avg = [r for r in rows if int(r["body_id"]) == 0]
    curves: list[figures.Curve] = []
    diffs: list[figures.Curve] = []
    key: list[figures.Curve] = []
    bodies = sorted({int(r["body_id"]) for r in rows if int(r["body_id"]) != 0})
    styles = ("o-", "^--", "s:")
    empty = np.zeros(0)
    for m, model in enumerate(models):
        style = styles[m % len(styles)]
        mine = sorted((r for r in avg if str(r["model"]) == model), key=lambda r: r["angle_deg"])
        if mine:
            curves.append(figures.Curve(np.array([r["angle_deg"] for r in mine]),
                                        np.array([r["cor_analysis"] for r in mine]), f"analysis: {model}", style,
                                        f"C{m}"))
        key.append(figures.Curve(empty, empty, model, style, "0.3"))
        for k, body_id in enumerate(bodies):
            pts = sorted((r for r in rows if str(r["model"]) == model and int(r["body_id"]) == body_id),
                         key=lambda r: r["angle_deg"])
            diffs.append(figures.Curve(np.array([r["angle_deg"] for r in pts]),
                                       np.array([r["difference"] for r in pts]), f"{model} body {body_id}", style,
                                       f"C{k % 10}"))
    key += [figures.Curve(empty, empty, f"body {b}", "-", f"C{k % 10}")
            for k, b in enumerate(bodies)]
    if avg:  # drawn last, on top of the models' curves
        exp = sorted({float(r["angle_deg"]): r for r in avg if str(r["model"]) == models[0]}.items())
        curves.append(figures.Curve(np.array([a for a, _ in exp]), np.array([r["cor_experiment"] for _, r in exp]),
                                    "experiment", "s", "k"))
    png = figures.fig13_figure(curves, diffs, key)
    parts.append(figure(png, (
        "The paper's Fig. 13: (a) controlled-overturning rate COR = overturns towards the low side / overturns [%] "
        "against the plate inclination β [°], averaged over the bodies, from the models run on the measured plate "
        "motion (analysis) and from the detections (experiment); (b) analysis − experiment per body [percentage "
        "points], dashed ±5 pp (the paper's largest difference)."), alt="Fig. 13 analysis against experiment"))
    maxima = [(f"largest |difference|, {k.removeprefix('max_difference_')}", f"{num(v, '.1f', 100)} pp")
              for k, v in sorted(header.analysis_attrs.items()) if k.startswith("max_difference_")]
    margin = header.analysis_attrs.get("margin")
    margin_pp = f"{100 * float(margin):g}" if margin is not None else "5"
    parts.append(key_values(_impact_model(header.analysis_attrs) + maxima
                            + [("equivalence margin", f"±{margin_pp} pp")]))
    if any(split_label(str(r["model"]))[1] for r in rows):
        parts.append(_rules_table(rows, names, margin_pp))
    ordered = sorted(rows, key=lambda r: (str(r["model"]), float(r["angle_deg"]), int(r["body_id"])))
    parts.append(table(
        ["model", "β [°]", "body", "runs", "analysis: low / overturned, COR [%]",
         "experiment: low / overturned, COR [%]", "difference [pp]", "McNemar p: side; overturn", "verdict"],
        [[r["model"], num(r["angle_deg"], "g"),
          "average" if int(r["body_id"]) == 0 else f"{r['body_id']} {names.get(int(r['body_id']), '')}".strip(),
          r["runs"], f"{r['towards_low_analysis']}/{r['overturned_analysis']}: {_rate(r, 'cor_analysis')}",
          f"{r['towards_low_experiment']}/{r['overturned_experiment']}: {_rate(r, 'cor_experiment')}",
          _difference(r), _mcnemar(r), _verdict(r)] for r in ordered],
        caption="Fig. 13 data: per model, angle and body. The models were re-run on each run's measured plate "
                "motion and their overturns compared case by case with the specimens'. COR with its 95 % interval "
                "(Wilson's where a body's records enter once; the cluster bootstrap over records where they are "
                "shared — the average row, one estimator, the mean of the bodies' CORs, with its own interval). "
                "Difference with its 90 % interval. McNemar: exact p of the paired cases that disagree, on the side "
                "(analysis low and specimen high against the reverse, counts in brackets) and on overturning "
                "(analysis only against experiment only). Verdict: equivalence of the two rates within "
                f"±{margin_pp} points by two one-sided tests at 5 % — equivalent, different (beyond the margin), or "
                "not resolved with the runs at hand (and how many would resolve it at the same rates).",
        left=3, row_classes=["avg" if int(r["body_id"]) == 0 else "" for r in ordered]))
    return "\n".join(parts)


RULE_NAMES = {"plastic": "plastic", "housner": "Housner's", "fit": "fitted"}
"""Column heads of the impact rules side by side."""


def _rules_table(rows: list[dict[str, Any]], names: dict[int, str], margin_pp: str) -> str:
    """Fig. 13 with each model under plastic, Housner's and fitted restitution side by side (``rig analyze
    --restitution all``): per model, angle and body the experiment's COR, then per rule the analysis's and the
    verdict."""
    groups = side_by_side(sorted(rows, key=lambda r: (split_label(str(r["model"]))[0], float(r["angle_deg"]),
                                                      int(r["body_id"]))))
    rules = list(dict.fromkeys(rule for *_, by_rule in groups for rule in by_rule))
    heads = ["model", "β [°]", "body", "experiment: COR [%]"]
    for rule in rules:
        heads += [f"{RULE_NAMES.get(rule, esc(rule))}: COR [%]", f"{RULE_NAMES.get(rule, esc(rule))}: verdict"]
    body_rows = []
    for model, angle, body_id, by_rule in groups:
        cells: list[Any] = [model, num(angle, "g"),
                            "average" if body_id == 0 else f"{body_id} {names.get(body_id, '')}".strip(),
                            _rate(dict(next(iter(by_rule.values()))), "cor_experiment")]
        for rule in rules:
            row = by_rule.get(rule)
            cells += ["–", "–"] if row is None else [_rate(dict(row), "cor_analysis"), _verdict(dict(row))]
        body_rows.append(cells)
    return table(heads, body_rows, left=3, row_classes=["avg" if g[2] == 0 else "" for g in groups], caption=(
        "Fig. 13 under three impact rules: the models re-run on the measured plate motion with plastic impacts "
        "(the paper's analysis), with Housner's restitution 1 − 1.5 sin²α, and with each body's restitution fitted "
        "from its measured free rocking; COR with its 95 % interval, the verdict of equivalence with the "
        f"experiment's COR within ±{margin_pp} points. Counts, differences and paired tests per rule: the table "
        "below (model:rule)."))


def _rate(row: dict[str, Any], name: str) -> str:
    """A COR [%] with its interval when the file has it (analysed before the intervals: the rate alone)."""
    rate = num(row[name], ".0f", 100)
    low, high = row.get(f"{name}_low"), row.get(f"{name}_high")
    if low is None or high is None or not (math.isfinite(low) and math.isfinite(high)):
        return rate
    return f"{rate} [{100 * low:.0f}–{100 * high:.0f}]"


def _difference(row: dict[str, Any]) -> str:
    """The difference [pp] with its 90 % interval when the file has it."""
    text = num(row["difference"], "+.0f", 100)
    low, high = row.get("difference_low"), row.get("difference_high")
    if low is None or high is None or not (math.isfinite(low) and math.isfinite(high)):
        return text
    return f"{text} [{100 * low:+.0f}, {100 * high:+.0f}]"


def _mcnemar(row: dict[str, Any]) -> str:
    """McNemar's exact p on the side and on overturning, with the discordant counts; ``–`` on the average row or an
    analysis stored before the paired tests."""
    side, overturn = row.get("p_direction"), row.get("p_overturn")
    if side is None or overturn is None or not (math.isfinite(side) and math.isfinite(overturn)):
        return "–"
    return (f"{side:.2f} ({row['low_high']}/{row['high_low']}); "
            f"{overturn:.2f} ({row['analysis_only']}/{row['experiment_only']})")


def _verdict(row: dict[str, Any]) -> str:
    """The equivalence verdict in words (``–`` for an analysis stored before the verdicts)."""
    verdict = row.get("verdict")
    if not verdict:
        return "–"
    return verdict_words(str(verdict), int(row["body_id"]), int(row["runs"]), int(row.get("runs_to_resolve", -1)))


def session_body(path: str, progress: Progress | None = None) -> tuple[str, str, int]:
    """(title, body HTML, number of figures) of the session report of ``path``."""
    header = read_header(path)
    seq = header.sequence or {}
    body_rows = list(seq.get("bodies", []) or [])
    names = _body_names(body_rows)
    sections, summaries = [], []
    n_figures = 0
    total = len(header.runs)
    drawer, tracker = figures.RunFigure(DEFAULT_PERIODS), figures.TrackingFigure()
    for k, run in enumerate(iter_runs(path)):
        if not body_rows and run.bodies:
            body_rows = run.bodies
            names = _body_names(body_rows)
        html, summary = run_section(run, names, drawer, header.rig_config, tracker)
        n_figures += html.count("<img ")
        sections.append(html)
        summaries.append(summary)
        if progress is not None:
            progress(k + 1, total)
    statuses: dict[str, int] = {}
    for s in summaries:
        statuses[s.status] = statuses.get(s.status, 0) + 1
    overturns = sum(0 if s.overturns == "–" else len(s.overturns.split()) for s in summaries)
    title = f"Shake-table session report — {seq.get('name') or header.path.stem}"
    head = [f"<h1>{esc(title)}</h1>", key_values([
        ("session file", header.path.name), ("created", header.created),
        ("software version", header.software_version),
        ("runs", f"{len(summaries)} (" + ", ".join(f"{v} {k}" for k, v in sorted(statuses.items())) + ")"),
        ("overturns detected", overturns),
        ("analysis", "yes (rig analyze)" if header.fig13 else "not analysed yet (rig analyze)")])]
    rig_html = _rig_section(header)
    seq_html = _sequence_section(header, body_rows)
    fig13_html = _fig13_section(header, names)
    compensation_html = compensation_section(path)
    n_figures += seq_html.count("<img ") + fig13_html.count("<img ") + compensation_html.count("<img ")
    body = "\n".join([*head, rig_html, seq_html, "<h2>Runs</h2>", _runs_table(summaries), _scale_table(header),
                      fig13_html, compensation_html, "<h2>Run by run</h2>", *sections])
    return title, body, n_figures
