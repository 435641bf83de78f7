"""The report of a study file (``rig study``'s saved results): the settings, Eq. 1's thresholds for the bodies
(the paper's Fig. 2), the COR curves with the fitted Eqs. 11 and 13 (Figs. 6–9), the fitted coefficients, and the
equivalents of Tables II (Eq. 11 against the angle) and III (the error estimators per body)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from analysis import design
from analysis.design import PAPER_C2, PAPER_GCOR, PAPER_SCOR
from rig.study_file import SavedStudy, StudyFileError, read_study

from . import figures
from .data import ReportError
from .html import esc, figure, key_values, num, table

TABLE2_ANGLES = np.arange(0.0, 7.01, 0.5)
"""The paper's Table II angles [deg]."""


def _curve(beta_deg: np.ndarray, c1: float, c2: float) -> np.ndarray:
    """Eqs. 11/13 (``analysis.design.gcor``: c2·tanh(β/c1) + 0.5) [fraction] at ``beta_deg`` [deg]."""
    return np.asarray(design.gcor(np.radians(beta_deg), c1, c2))


class StudyView:
    """What the study report draws, from the study file's own reader (``rig.study_file.read_study``): the bodies
    ({b, h, name} [m]), records, angles [deg], the ``cor`` and ``estimators`` tables as rows of plain values, the
    fits' attributes and the direction array."""

    def __init__(self, saved: SavedStudy) -> None:
        self.path = saved.path
        self.attrs = saved.attrs
        self.bodies: list[dict[str, Any]] = list(saved.attrs["bodies"])
        self.records = saved.records
        self.angles_deg = np.atleast_1d(np.asarray(saved.attrs.get("angles_deg", []), dtype=float))
        self.direction: np.ndarray | None = saved.direction
        self.cor = _plain_rows(saved.cor)
        self.estimators = _plain_rows(saved.estimators)
        self.gcor: dict[str, Any] | None = saved.fits.get("gcor") or None
        self.scor: dict[str, Any] | None = saved.fits.get("scor") or None


def _plain_rows(table: np.ndarray) -> list[dict[str, Any]]:
    """A structured array's rows as dicts of Python values (byte strings decoded)."""
    names = table.dtype.names or ()
    return [{name: value.decode() if isinstance(value, bytes) else value
             for name, value in zip(names, row.tolist(), strict=True)} for row in np.atleast_1d(table)]


def _f(fit: dict[str, Any] | None, key: str) -> float | None:
    if not fit or fit.get(key) is None:
        return None
    try:
        value = float(fit[key])
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def gcor_coefficients(study: StudyView) -> tuple[float, float] | None:
    """The fitted Eq. 11 (c1 [rad], c2), None if the study has none."""
    c1, c2 = _f(study.gcor, "c1"), _f(study.gcor, "c2")
    return (c1, c2) if c1 is not None and c2 is not None and c1 > 0 else None


def scor_coefficients(study: StudyView) -> tuple[float, float, float, float] | None:
    """The fitted Eq. 13 (k1, k2, k3, c2), None if the study has none (c2 defaults to the paper's 0.48)."""
    k1, k2, k3 = (_f(study.scor, k) for k in ("k1", "k2", "k3"))
    if k1 is None or k2 is None or k3 is None:
        return None
    c2 = _f(study.scor, "c2")
    return (k1, k2, k3, PAPER_C2 if c2 is None else c2)


def _rows(study: StudyView, body_index: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rows = sorted((r for r in study.cor if int(r["body_index"]) == body_index), key=lambda r: r["angle_deg"])
    return (np.array([float(r["angle_deg"]) for r in rows]), np.array([float(r["cor"]) for r in rows]),
            np.array([int(r["overturned"]) for r in rows]))


def _label(study: StudyView, j: int) -> str:
    body = study.bodies[j]
    name = body.get("name") or f"{j + 1}"
    return f"{name}: {float(body['b']):g}×{float(body['h']):g} m"


def _settings(study: StudyView) -> str:
    a = study.attrs
    recs = study.records
    shown = ", ".join(recs[:40]) + (f", … ({len(recs) - 40} more)" if len(recs) > 40 else "")
    return key_values([
        ("study file", study.path.name), ("created", a.get("created")), ("software version", a.get("software_version")),
        ("model", a.get("model")), ("restitution", a.get("restitution")), ("friction", a.get("friction")),
        ("bodies", len(study.bodies)), ("records", f"{len(recs)}: {shown}"),
        ("angles", ", ".join(f"{x:g}°" for x in study.angles_deg)),
        ("scenes", f"{a.get('scenes')} (bodies × records × both signs × angles) in {num(a.get('seconds'), '.1f')} s"
                   f" on {a.get('where', '–')}"),
    ])


def _thresholds(study: StudyView) -> str:
    aspects: dict[float, list[str]] = {}
    for j, b in enumerate(study.bodies):
        aspects.setdefault(round(float(b["b"]) / float(b["h"]), 4), []).append(str(b.get("name") or j + 1))
    labels = [(x, f"b/h = {x:.3g} ({', '.join(ids)})") for x, ids in sorted(aspects.items())]
    top = max(7.0, float(study.angles_deg.max()) if study.angles_deg.size else 7.0)
    png = figures.thresholds_figure(labels, top)
    return figure(png, (
        "Eq. 1 (the paper's Fig. 2): the horizontal acceleration [g] that starts rocking towards the low side "
        "(A<sub>min+</sub> = tan(α − β), solid) and the high side (A<sub>min−</sub> = tan(α + β), dashed) against "
        "the plate inclination β [°], no vertical acceleration; one colour per aspect ratio b/h (bodies in "
        "brackets)."), alt="Eq. 1 thresholds against angle")


def _cor_figures(study: StudyView, gcor: tuple[float, float] | None,
                 scor: tuple[float, float, float, float] | None) -> str:
    fine = np.linspace(0.0, max(7.0, float(study.angles_deg.max()) if study.angles_deg.size else 7.0), 141)
    parts = []
    angles, cor, _ = _rows(study, -1)
    curves = [figures.Curve(angles, cor, "analysis, average over the bodies", "o", "k")]
    if gcor:
        curves.append(figures.Curve(fine, _curve(fine, *gcor), f"Eq. 11 fitted: c1 = {gcor[0]:.4f}, c2 = {gcor[1]:.3f}",
                                    "-", "C0"))
    curves.append(figures.Curve(fine, _curve(fine, *PAPER_GCOR), "Eq. 11, paper: c1 = 0.048, c2 = 0.48", "--", "0.5"))
    parts.append(figure(figures.cor_figure(curves), (
        "Controlled-overturning rate COR = overturns towards the low side / overturns [%] against the plate "
        "inclination β [°]: the average over the bodies of the analysis (bodies with no overturn at an angle left "
        "out), Eq. 11 (GCOR = c2·tanh(β/c1) + 0.5, β in rad) fitted to it and with the paper's coefficients (the "
        "paper's Figs. 6–7)."), alt="average COR against angle with Eq. 11"))
    panels = []
    for j, body in enumerate(study.bodies):
        a, c, _ = _rows(study, j)
        pc = [figures.Curve(a, c, "analysis", "o", "k")]
        if gcor:
            pc.append(figures.Curve(fine, _curve(fine, *gcor), "Eq. 11 (GCOR) fitted", "-", "C0"))
        if scor:
            c1 = float(design.scor_c1((float(body["b"]), float(body["h"])), scor[:3]))
            if c1 > 0:
                pc.append(figures.Curve(fine, _curve(fine, c1, scor[3]), "Eq. 13 (SCOR) fitted", "-", "C3"))
        panels.append((_label(study, j), pc))
    if panels:
        parts.append(figure(figures.cor_grid_figure(panels), (
            "COR [%] against β [°] per body (the paper's Figs. 8–9): the analysis, Eq. 11 (GCOR, the same for all "
            "bodies) and Eq. 13 (SCOR: c1 = k1·b/h + k2·r + k3, r = √((b/2)² + (h/2)²) in m) with the fitted "
            "coefficients."), alt="COR per body with Eqs. 11 and 13"))
    return "\n".join(parts)


def _fits(study: StudyView, gcor: tuple[float, float] | None, scor: tuple[float, ...] | None) -> str:
    def ci(fit: dict[str, Any] | None, key: str) -> str:
        lo, hi = _f(fit, f"{key}_ci_low"), _f(fit, f"{key}_ci_high")
        if lo is None or hi is None:
            return "– (held fixed)" if key == "c2" else "–"
        return f"{lo:.4g} – {hi:.4g}"

    rows = []
    if gcor:
        rows += [["Eq. 11 (GCOR)", "c1 [rad]", f"{gcor[0]:.4f}", ci(study.gcor, "c1"), f"{PAPER_GCOR[0]:g}"],
                 ["Eq. 11 (GCOR)", "c2", f"{gcor[1]:.4f}", ci(study.gcor, "c2"), f"{PAPER_GCOR[1]:g}"]]
    if scor:
        paper = (*PAPER_SCOR, PAPER_C2)
        for i, (key, unit) in enumerate((("k1", "rad"), ("k2", "rad/m"), ("k3", "rad"), ("c2", ""))):
            rows.append(["Eq. 13 (SCOR)", f"{key} [{unit}]" if unit else key, f"{scor[i]:.4f}", ci(study.scor, key),
                         f"{paper[i]:g}"])
    notes = []
    for name, fit in (("Eq. 11", study.gcor), ("Eq. 13", study.scor)):
        if fit and fit.get("error"):
            notes.append(f'<p class="warn">{name} could not be fitted: {esc(fit["error"])}</p>')
        elif not fit:
            notes.append(f'<p class="note">{name}: no fit in the study file.</p>')
    if not rows:
        return "\n".join(notes)
    return table(["equation", "coefficient", "fitted", "95 % confidence interval", "paper"], rows,
                 caption="Fitted coefficients", left=2) + "\n".join(notes)


def _table2(study: StudyView, gcor: tuple[float, float] | None) -> str:
    angles, cor, _ = _rows(study, -1)
    observed = {round(float(a), 6): c for a, c in zip(angles, cor, strict=True)}
    head = ["β [°]", *[f"{a:g}" for a in TABLE2_ANGLES]]
    rows = []
    if gcor:
        rows.append(["Eq. 11 fitted [%]", *[f"{100 * v:.0f}" for v in _curve(TABLE2_ANGLES, *gcor)]])
    rows.append(["Eq. 11 paper [%]", *[f"{100 * v:.0f}" for v in _curve(TABLE2_ANGLES, *PAPER_GCOR)]])
    rows.append(["analysis, average [%]", *[num(observed.get(round(float(a), 6)), ".0f", 100) for a in TABLE2_ANGLES]])
    return table(head, rows, left=1, caption=(
        "Table II equivalent: the controlled-overturning rate from Eq. 11 for inclinations 0–7°, with the paper's "
        "coefficients and the analysis' body average where the study has that angle"))


def _cor_table(study: StudyView) -> str:
    angles = sorted({float(r["angle_deg"]) for r in study.cor})
    by = {(int(r["body_index"]), float(r["angle_deg"])): r for r in study.cor}
    head = ["β [°]", *[esc(b.get("name") or j + 1) for j, b in enumerate(study.bodies)], "average", "overturned"]
    rows = []
    for a in angles:
        cells = [num(by.get((j, a), {}).get("cor"), ".0f", 100) for j in range(len(study.bodies))]
        avg = by.get((-1, a), {})
        total = sum(int(by.get((j, a), {}).get("overturned", 0)) for j in range(len(study.bodies)))
        rows.append([f"{a:g}", *cells, num(avg.get("cor"), ".0f", 100), total])
    return table(head, rows, caption=(
        "COR [%] per body and angle (– where nothing overturned); overturned: scenes that overturned at that "
        "angle, all bodies"))


def _table3(study: StudyView) -> str:
    est: dict[tuple[int, str], dict[str, Any]] = {(int(e["body_index"]), str(e["equation"]).upper()): e
                                                    for e in study.estimators}
    if not est:
        return '<p class="note">Table III: no error estimators in the study file.</p>'
    head = ["body", "base [m]", "height [m]", "b/h", "r [m]", "α [rad]", "max diff. GCOR [%]", "max diff. SCOR [%]",
            "abs. area GCOR", "abs. area SCOR", "error GCOR [%]", "error SCOR [%]"]
    rows, classes = [], []
    indices = sorted({j for j, _ in est}, key=lambda j: (j < 0, j))
    for j in indices:
        g, s = est.get((j, "GCOR"), {}), est.get((j, "SCOR"), {})
        if 0 <= j < len(study.bodies):
            b, h = float(study.bodies[j]["b"]), float(study.bodies[j]["h"])
            geo = [study.bodies[j].get("name") or j + 1, f"{b:.2f}", f"{h:.2f}", f"{b / h:.2f}",
                   f"{0.5 * math.hypot(b, h):.2f}", f"{math.atan2(b, h):.2f}"]
        else:
            geo = ["average", "", "", "", "", ""]
        rows.append([*geo, num(g.get("max_difference"), ".0f"), num(s.get("max_difference"), ".0f"),
                     num(g.get("absolute_area"), ".2f"), num(s.get("absolute_area"), ".2f"),
                     num(g.get("error"), ".0f"), num(s.get("error"), ".0f")])
        classes.append("avg" if j < 0 else "")
    return table(head, rows, left=1, row_classes=classes, caption=(
        "Table III equivalent: error estimators of Eq. 11 (GCOR) and Eq. 13 (SCOR) against the analysis. Max "
        "difference: analysis − equation at the angle of the largest |difference| [percentage points; positive: "
        "the equation under-predicts]; absolute area: ∫|difference| dβ [% · degrees]; error: Eq. 12 [%]"))


def _outcomes(study: StudyView) -> str:
    d = study.direction
    if d is None or d.ndim != 4 or d.shape[0] != len(study.bodies):
        return ""
    rows = []
    for j in range(d.shape[0]):
        x = d[j]
        rows.append([_label(study, j), x.size, int(np.count_nonzero(x)), int(np.count_nonzero(x == 1)),
                     int(np.count_nonzero(x == -1))])
    return table(["body", "scenes", "overturned", "towards the low side", "towards the high side"], rows, left=1,
                 caption="Outcomes per body (all records, both signs, all angles)")


def study_body(path: str) -> tuple[str, str, int]:
    """(title, body HTML, number of figures) of the study report of ``path``."""
    try:
        study = StudyView(read_study(path))
    except StudyFileError as exc:
        raise ReportError(str(exc)) from None
    gcor, scor = gcor_coefficients(study), scor_coefficients(study)
    title = f"Analytical study report — {study.attrs.get('model', '?')} model, {len(study.bodies)} bodies, " \
            f"{len(study.records)} records"
    parts = [f"<h1>{esc(title)}</h1>", _settings(study), "<h2>Uplift thresholds (Eq. 1)</h2>", _thresholds(study),
             "<h2>Controlled-overturning rate</h2>", _cor_figures(study, gcor, scor), _fits(study, gcor, scor),
             _table2(study, gcor), _cor_table(study), "<h2>Error estimators (Table III)</h2>", _table3(study),
             "<h2>Outcomes</h2>", _outcomes(study)]
    body = "\n".join(parts)
    return title, body, body.count("<img ")
