"""The summary of a study as ``rig study`` prints and saves it: COR, fitted Eqs. 11 and 13 beside the paper's,
Eq. 12 errors and Table III's estimators for both equations.

Rates are fractions in the dict (percent only in the printed tables), angles in degrees where the key says
``_deg`` and radians otherwise. Table III's estimators (``analysis.design.table3_estimators``): max difference
[percentage points, observed − equation], absolute area [% · degrees], error [%] (Eq. 12 × 100). They are given
for each body and each equation, with the paper's coefficients (as Table III) and with the fitted ones; for a
Table I body the paper's printed Table III values stand beside ours.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from rich import box
from rich.markup import escape
from rich.table import Table

from analysis.body import TABLE_I, Body
from analysis.design import PAPER_C2, PAPER_GCOR, PAPER_SCOR, gcor, scor, table3_estimators
from analysis.errors import AnalysisInputError
from analysis.study import StudyResult

PAPER_TABLE_III: dict[int, dict[str, tuple[float, float, float]]] = {
    1: {"GCOR": (3, 5.01, 1), "SCOR": (-2, 5.21, 1)},
    2: {"GCOR": (9, 15.57, 3), "SCOR": (10, 8.22, 2)},
    3: {"GCOR": (-7, 16.83, 3), "SCOR": (5, 5.86, 2)},
    4: {"GCOR": (9, 12.39, 3), "SCOR": (7, 13.22, 3)},
    5: {"GCOR": (-3, 9.23, 2), "SCOR": (-3, 5.87, 1)},
    6: {"GCOR": (-5, 13.90, 3), "SCOR": (-2, 6.65, 2)},
    7: {"GCOR": (-37, 63.12, 13), "SCOR": (-29, 40.98, 9)},
    8: {"GCOR": (14, 31.50, 6), "SCOR": (8, 11.65, 3)},
    9: {"GCOR": (10, 17.61, 4), "SCOR": (7, 9.23, 2)},
    10: {"GCOR": (7, 12.39, 3), "SCOR": (6, 12.35, 3)},
    11: {"GCOR": (14, 41.16, 8), "SCOR": (4, 6.04, 1)},
    12: {"GCOR": (7, 15.13, 4), "SCOR": (-16, 14.91, 3)},
}
"""The paper's Table III per Table I body number: equation → (max difference [pp], absolute area [% · deg],
error [%]), as printed."""

EQUATIONS = ("GCOR", "SCOR")
COEFFICIENT_SETS = ("paper", "fitted")


def table1_number(body: Body) -> int | None:
    """The 1-based Table I number of a body with the same b and h [m], else None."""
    for i, row in enumerate(TABLE_I, start=1):
        if math.isclose(row.b, body.b, abs_tol=1e-9) and math.isclose(row.h, body.h, abs_tol=1e-9):
            return i
    return None


def _curve(equation: str, coefficients: str, body: Body, beta: np.ndarray, fits: dict[str, Any]) -> np.ndarray:
    """The equation's rates at ``beta`` [rad] for ``body`` with the paper's or the fitted coefficients."""
    if equation == "GCOR":
        c1, c2 = PAPER_GCOR if coefficients == "paper" else (fits["gcor"]["c1"], fits["gcor"]["c2"])
        return np.asarray(gcor(beta, c1, c2))
    if coefficients == "paper":
        return np.asarray(scor(beta, body, PAPER_SCOR, PAPER_C2))
    f = fits["scor"]
    return np.asarray(scor(beta, body, (f["k1"], f["k2"], f["k3"]), f["c2"]))


def estimators(res: StudyResult, fits: dict[str, Any]) -> list[dict[str, Any]]:
    """Table III's estimators per body × equation × coefficient set (``fits``: the summary's ``gcor`` and
    ``scor`` entries; a set whose fit failed is left out). A body with no overturn at any angle, or one
    outside Eq. 13's range (c1 ≤ 0), gets ``None`` values and an ``error_message``."""
    rows = res.cor()
    na = len(res.angles)
    out: list[dict[str, Any]] = []
    for j, body in enumerate(res.bodies):
        observed = np.array([np.nan if r["cor"] is None else r["cor"] for r in rows[j * na:(j + 1) * na]])
        number = table1_number(body)
        for equation in EQUATIONS:
            for coefficients in COEFFICIENT_SETS:
                if coefficients == "fitted" and "error" in fits[equation.lower()]:
                    continue
                row: dict[str, Any] = {"body_index": j, "body": body.label(), "b": body.b, "h": body.h,
                                       "table1": number, "equation": equation, "coefficients": coefficients}
                try:
                    est = table3_estimators(res.angles, observed, _curve(equation, coefficients, body,
                                                                         res.angles, fits))
                    row.update(est)
                except AnalysisInputError as exc:
                    row.update({"max_difference": None, "absolute_area": None, "error": None,
                                "error_message": str(exc)})
                paper = PAPER_TABLE_III.get(number or 0, {}).get(equation)
                row["paper"] = (dict(zip(("max_difference", "absolute_area", "error"), paper, strict=True))
                                if paper and coefficients == "paper" else None)
                out.append(row)
    return out


def study_summary(res: StudyResult) -> dict[str, Any]:
    """The ``rig study --json`` object: :meth:`StudyResult.summary` (docs/architecture.md §7; keys ``cor``, ``gcor``,
    ``scor``, ``scenes``, ``seconds``) plus ``where`` ("local" or the Dask scheduler's address), ``paper``
    (the printed coefficients), ``scor_paper`` (Eq. 12 error of the paper's Eq. 13 over every body's rates),
    ``scor`` gains ``eq12_error`` (the same for the fitted Eq. 13) and ``estimators`` (Table III)."""
    out = res.summary()
    out["where"] = str(res.settings.get("where", "local"))
    out["records"] = list(res.records)
    out["bodies"] = [{"b": b.b, "h": b.h, "name": b.name, "table1": table1_number(b)} for b in res.bodies]
    out["paper"] = {"gcor": {"c1": PAPER_GCOR[0], "c2": PAPER_GCOR[1]},
                    "scor": {"k1": PAPER_SCOR[0], "k2": PAPER_SCOR[1], "k3": PAPER_SCOR[2], "c2": PAPER_C2}}
    est = estimators(res, out)
    out["scor_paper"] = {**out["paper"]["scor"], "eq12_error": _pooled_error(res, out, "paper")}
    if "error" not in out["scor"]:
        out["scor"]["eq12_error"] = _pooled_error(res, out, "fitted")
    out["estimators"] = est
    return out


def _pooled_error(res: StudyResult, fits: dict[str, Any], coefficients: str) -> float | None:
    """Eq. 12 (fraction) of Eq. 13 over every (body, angle) rate at once; None if undefined anywhere."""
    rows = res.cor()
    na = len(res.angles)
    observed, fitted = [], []
    try:
        for j, body in enumerate(res.bodies):
            curve = _curve("SCOR", coefficients, body, res.angles, fits)
            for m in range(na):
                cor = rows[j * na + m]["cor"]
                if cor is not None:
                    observed.append(cor)
                    fitted.append(float(curve[m]))
    except AnalysisInputError:
        return None
    if not observed:
        return None
    from analysis.design import eq12_error

    return eq12_error(observed, fitted)


# --------------------------------------------------------------------------------------------------
# Printed tables


def _num(x: float | None, fmt: str) -> str:
    return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, fmt)


def _ci(ci: list[float] | None, fmt: str) -> str:
    return "fixed" if ci is None else f"{ci[0]:{fmt}} – {ci[1]:{fmt}}"


def coefficient_table(summary: dict[str, Any]) -> Table:
    """Our fitted coefficients (95 % CI) beside the paper's, with Eq. 12 errors (%)."""
    table = Table(box=box.SIMPLE_HEAD, title="Design equations: fitted to this study beside the paper's")
    for name in ("equation", "coefficient", "fitted", "95 % CI", "paper"):
        table.add_column(name, justify="left" if name in ("equation", "coefficient") else "right")
    g, s, paper = summary["gcor"], summary["scor"], summary["paper"]
    if "error" in g:
        table.add_row("GCOR (Eq. 11)", "–", escape(f"fit failed: {g['error']}"), "", "")
    else:
        table.add_row("GCOR (Eq. 11)", escape("c1 [rad]"), f"{g['c1']:.4f}", _ci(g["c1_ci"], ".4f"),
                      f"{paper['gcor']['c1']:g}")
        table.add_row("", "c2", f"{g['c2']:.4f}", _ci(g["c2_ci"], ".4f"), f"{paper['gcor']['c2']:g}")
        table.add_row("", "Eq. 12 error (average) %", _num(100 * g["eq12_error"], ".2f"), "",
                      _num(100 * summary["gcor_paper"]["eq12_error"], ".2f"))
    if "error" in s:
        table.add_row("SCOR (Eq. 13)", "–", escape(f"fit failed: {s['error']}"), "", "")
    else:
        labels = {"k1": escape("k1 (× b/h) [rad]"), "k2": escape("k2 (× r) [rad/m]"), "k3": escape("k3 [rad]"),
                  "c2": "c2"}
        for i, key in enumerate(("k1", "k2", "k3", "c2")):
            ci = s["ci"].get(key)
            table.add_row("SCOR (Eq. 13)" if i == 0 else "", labels[key], f"{s[key]:.4f}",
                          _ci(ci, ".4f") if key in s["ci"] else "fixed", f"{paper['scor'][key]:g}")
        table.add_row("", "Eq. 12 error (all bodies) %", _num(None if s.get("eq12_error") is None
                                                             else 100 * s["eq12_error"], ".2f"), "",
                      _num(None if summary["scor_paper"]["eq12_error"] is None
                           else 100 * summary["scor_paper"]["eq12_error"], ".2f"))
    return table


def estimator_table(summary: dict[str, Any]) -> Table:
    """Table III per body and equation: max difference [pp], absolute area [% · deg] and error [%] against this
    study with the paper's coefficients, the paper's printed values (Table I bodies) and with the fitted ones."""
    table = Table(box=box.SIMPLE_HEAD, title="Table III estimators against this study",
                  caption=escape("max Δ: observed − equation [pp] at the worst angle; area: ∫|Δ| dβ [% · deg]; "
                                 "err: Eq. 12 [%]"))
    table.add_column("body", justify="right")
    table.add_column("eq.")
    for group in ("paper's eq.", "Table III", "fitted eq."):
        for what in ("max Δ", "area", "err"):
            table.add_column(f"{group}\n{what}", justify="right")
    by_key = {(r["body_index"], r["equation"], r["coefficients"]): r for r in summary["estimators"]}
    keys = (("max_difference", ".0f"), ("absolute_area", ".2f"), ("error", ".1f"))
    for j, body in enumerate(summary["bodies"]):
        label = str(body["table1"]) if body["table1"] else f"{body['b']:g}x{body['h']:g}"
        for equation in EQUATIONS:
            paper_row, fitted_row = by_key.get((j, equation, "paper")), by_key.get((j, equation, "fitted"))
            printed = (paper_row or {}).get("paper") or {}
            cells = [_num(None if r is None else r[k], fmt) for r in (paper_row,) for k, fmt in keys]
            cells += [_num(printed.get(k), "g") for k, _ in keys]
            cells += [_num(None if fitted_row is None else fitted_row[k], fmt) for k, fmt in keys]
            table.add_row(label if equation == EQUATIONS[0] else "", equation, *cells,
                          end_section=equation == EQUATIONS[-1])
    return table
