"""The paper's design equations for controlled overturning, their fits to any study, and the inverse.

Units in this API (docs/architecture.md §2): the inclination β is in **radians** (degrees only at the CLI),
controlled-overturning rates (COR) are **fractions** in [0, 1], lengths are metres.

- Eq. 11 (GCOR, the average over all bodies): ``COR(β) = c2·tanh(β / c1) + 0.5`` with the paper's
  c1 = 0.048 rad, c2 = 0.48 (:data:`PAPER_GCOR`).
- Eq. 13 (SCOR, body-specific): the same curve with ``c1 = k1·(b/h) + k2·r + k3``, r = sqrt((b/2)² + (h/2)²)
  [m], paper k = (0.1136, −0.0283, 0.0279) (:data:`PAPER_SCOR`), c2 = 0.48.
- Eq. 12 (error): ``sqrt(Σ (Xi − Xf)² / Σ Xf²)``, Xi the observed (analytical) rates, Xf the fitted ones.

The curve starts at 0.5 for β = 0 and never exceeds ``0.5 + c2`` (0.98 with the paper's c2): a target
confidence at or above that is unreachable at any inclination.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Literal, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import integrate, optimize, stats

from analysis.body import Body
from analysis.errors import AnalysisInputError

PAPER_GCOR: tuple[float, float] = (0.048, 0.48)
"""Eq. 11 coefficients (c1 [rad], c2 [-]) as printed in the paper."""

PAPER_SCOR: tuple[float, float, float] = (0.1136, -0.0283, 0.0279)
"""Eq. 13 coefficients (k1 [rad], k2 [rad/m], k3 [rad]) of c1 = k1·(b/h) + k2·r + k3."""

PAPER_C2: float = 0.48
"""The amplitude c2 of Eqs. 11 and 13 in the paper [-]."""

CONFIDENCE_LEVEL: float = 0.95
"""Level of the confidence intervals reported by the fits."""

Equation = Literal["SCOR", "GCOR"]
FloatOrArray = float | NDArray[np.float64]


# --------------------------------------------------------------------------------------------------
# Eqs. 11 and 13


def _tanh_curve(beta: ArrayLike, c1: ArrayLike, c2: float) -> FloatOrArray:
    """``c2·tanh(β/c1) + 0.5`` without checks (shared by the public functions and the fits)."""
    out = np.tanh(np.asarray(beta, dtype=float) / np.asarray(c1, dtype=float)) * c2 + 0.5
    return float(out) if np.ndim(out) == 0 else out


def _check_curve_coefficients(c1: ArrayLike, c2: float, where: str) -> None:
    c1_arr = np.asarray(c1, dtype=float)
    if not np.all(np.isfinite(c1_arr)) or np.any(c1_arr <= 0):
        raise AnalysisInputError(f"{where}: c1 must be a finite angle > 0 rad, got {c1!r}")
    if not (math.isfinite(c2) and 0 < c2 <= 0.5):
        raise AnalysisInputError(f"{where}: c2 must be in (0, 0.5] so that COR stays in [0, 1], got {c2!r}")


def gcor(beta: ArrayLike, c1: float = PAPER_GCOR[0], c2: float = PAPER_GCOR[1]) -> FloatOrArray:
    """Eq. 11, the general controlled-overturning rate ``tanh(β/c1)·c2 + 0.5``.

    ``beta`` is the plate inclination [rad] (scalar or array); returns the rate as a fraction
    (a float for scalar input, else an array of the same shape).
    """
    _check_curve_coefficients(c1, c2, "gcor (Eq. 11)")
    return _tanh_curve(beta, c1, c2)


def _c1_linear(aspect: ArrayLike, r: ArrayLike, coeffs: Sequence[float]) -> FloatOrArray:
    k1, k2, k3 = coeffs
    out = k1 * np.asarray(aspect, dtype=float) + k2 * np.asarray(r, dtype=float) + k3
    return float(out) if np.ndim(out) == 0 else out


Vector = NDArray[np.float64]


def _body_b_h(body_or_b_h: Body | tuple[ArrayLike, ArrayLike]) -> tuple[Vector, Vector]:
    if isinstance(body_or_b_h, Body):
        return np.asarray(body_or_b_h.b, dtype=float), np.asarray(body_or_b_h.h, dtype=float)
    try:
        b, h = body_or_b_h
    except (TypeError, ValueError):
        raise AnalysisInputError(f"expected a Body or a (b, h) pair in metres, got {body_or_b_h!r}") from None
    b_arr, h_arr = np.asarray(b, dtype=float), np.asarray(h, dtype=float)
    both = np.concatenate([b_arr.ravel(), h_arr.ravel()])
    if not (np.all(np.isfinite(both)) and np.all(both > 0)):
        raise AnalysisInputError(f"b and h must be finite lengths > 0 m, got b={b!r}, h={h!r}")
    return b_arr, h_arr


def scor_c1(
    body_or_b_h: Body | tuple[ArrayLike, ArrayLike], coeffs: Sequence[float] = PAPER_SCOR
) -> FloatOrArray:
    """The SCOR time-constant of Eq. 13, ``c1 = k1·(b/h) + k2·r + k3`` [rad].

    ``body_or_b_h`` is a :class:`Body` or a pair ``(b, h)`` in metres (scalars or arrays);
    r = sqrt((b/2)² + (h/2)²) is the half-diagonal [m]. ``coeffs`` = (k1, k2, k3). The value is
    returned as computed, even when ≤ 0 (outside the bodies the paper fitted); :func:`scor` and
    :func:`design_angle` reject c1 ≤ 0.
    """
    if len(coeffs) != 3:
        raise AnalysisInputError(f"scor_c1: coeffs must be (k1, k2, k3), got {coeffs!r}")
    b, h = _body_b_h(body_or_b_h)
    return _c1_linear(b / h, 0.5 * np.hypot(b, h), coeffs)


def scor(
    beta: ArrayLike, body: Body | tuple[ArrayLike, ArrayLike], coeffs: Sequence[float] = PAPER_SCOR,
    c2: float = PAPER_C2,
) -> FloatOrArray:
    """Eq. 13, the specific controlled-overturning rate ``tanh(β/c1)·c2 + 0.5`` with c1 from :func:`scor_c1`.

    ``beta`` [rad]; ``body`` a :class:`Body` or ``(b, h)`` [m]; returns the rate as a fraction.
    Raises :class:`AnalysisInputError` when c1 ≤ 0 for the body (Eq. 13 extrapolated too far).
    """
    c1 = scor_c1(body, coeffs)
    _check_curve_coefficients(c1, c2, f"scor (Eq. 13) for body {_describe(body)}")
    return _tanh_curve(beta, c1, c2)


def _describe(body: object) -> str:
    if isinstance(body, Body):
        return body.label()
    return repr(body)


# --------------------------------------------------------------------------------------------------
# Eq. 12 and the Table III estimators


def _paired(observed: ArrayLike, fitted: ArrayLike, where: str) -> tuple[NDArray[np.float64], ...]:
    """Flatten two equal-shaped arrays and drop pairs where either is NaN (COR undefined: no overturn)."""
    obs, fit = np.asarray(observed, dtype=float), np.asarray(fitted, dtype=float)
    if obs.shape != fit.shape:
        raise AnalysisInputError(f"{where}: observed {obs.shape} and fitted {fit.shape} differ in shape")
    keep = ~(np.isnan(obs) | np.isnan(fit))
    if not keep.any():
        raise AnalysisInputError(f"{where}: no pair with both values defined")
    if not (np.all(np.isfinite(obs[keep])) and np.all(np.isfinite(fit[keep]))):
        raise AnalysisInputError(f"{where}: values must be finite")
    return obs[keep], fit[keep], keep


def eq12_error(observed: ArrayLike, fitted: ArrayLike) -> float:
    """Eq. 12, ``sqrt(Σ (Xi − Xf)² / Σ Xf²)``, as a fraction (Table III prints it × 100).

    ``observed`` are the reference rates Xi (the analytical results in the paper), ``fitted`` the
    equation's Xf at the same points; units cancel. Pairs with a NaN are skipped.
    """
    obs, fit, _ = _paired(observed, fitted, "eq12_error")
    denominator = float(np.sum(fit**2))
    if denominator == 0.0:
        raise AnalysisInputError("eq12_error: the fitted values are all zero (Eq. 12 undefined)")
    return math.sqrt(float(np.sum((obs - fit) ** 2)) / denominator)


def table3_estimators(angles_rad: ArrayLike, observed: ArrayLike, fitted: ArrayLike) -> dict[str, float]:
    """The three error estimators of the paper's Table III for one body.

    Inputs: inclinations β [rad] and the observed and fitted rates as fractions at those angles
    (pairs with a NaN rate are skipped; angles need not be sorted). Returns

    - ``max_difference`` [percentage points]: the signed ``100·(observed − fitted)`` at the angle where
      ``|observed − fitted|`` is largest (the first such angle on ties). Positive means the equation
      under-predicts (is conservative); the paper's −37 for body 7 (GCOR) is a body whose
      analytical rate lies below Eq. 11, consistent with its SCOR c1 (0.061) being above 0.048.
    - ``absolute_area`` [% · degrees]: the trapezoidal ∫ |observed − fitted| dβ with the rate in % and
      β in **degrees**. These are the units of Table III's magnitudes (5–63 over 0–7°: with β in rad
      the largest possible area would be 0.122 rad × 100 % ≈ 12, with rates as fractions ≤ 7).
      The trapezoid is taken on |difference| at the sample points, as a tabulated curve would be.
    - ``error`` [%]: Eq. 12 × 100.
    """
    beta = np.asarray(angles_rad, dtype=float)
    if beta.shape != np.shape(observed):
        raise AnalysisInputError(f"table3_estimators: angles {beta.shape} and rates {np.shape(observed)} "
                                 f"differ in shape")
    obs, fit, keep = _paired(observed, fitted, "table3_estimators")
    beta = beta[keep]
    if not np.all(np.isfinite(beta)):
        raise AnalysisInputError("table3_estimators: angles must be finite")
    for name, values in (("observed", obs), ("fitted", fit)):
        if np.any(values < 0) or np.any(values > 1):
            raise AnalysisInputError(f"table3_estimators: {name} rates must be fractions in [0, 1] "
                                     f"(0.95 = 95 %), got values up to {values.max():g}")
    order = np.argsort(beta, kind="stable")
    beta_deg, diff_pct = np.degrees(beta[order]), 100.0 * (obs[order] - fit[order])
    worst = int(np.argmax(np.abs(diff_pct)))
    return {
        "max_difference": float(diff_pct[worst]),
        "absolute_area": float(integrate.trapezoid(np.abs(diff_pct), beta_deg)) if beta.size > 1 else 0.0,
        "error": 100.0 * eq12_error(obs, fit),
    }


# --------------------------------------------------------------------------------------------------
# Fits


@dataclass(frozen=True)
class GcorFit:
    """Eq. 11 fitted to a set of (β, COR) points.

    ``c1`` [rad], ``c2`` [-] with their 95 % confidence intervals (t-distribution on the
    linearised covariance, see :func:`fit_gcor`); ``c2_ci`` is None when c2 was held fixed.
    ``rms`` is the (count-weighted) root-mean-square residual in COR fraction; ``n`` the points used.
    """

    c1: float
    c2: float
    c1_ci: tuple[float, float]
    c2_ci: tuple[float, float] | None
    rms: float
    n: int
    c2_fixed: bool

    @property
    def coeffs(self) -> tuple[float, float]:
        """(c1, c2), as :func:`gcor` and :func:`design_angle` take them."""
        return (self.c1, self.c2)

    def as_dict(self) -> dict[str, object]:
        """A JSON-ready dict."""
        return {"c1": self.c1, "c2": self.c2, "c1_ci": list(self.c1_ci),
                "c2_ci": None if self.c2_ci is None else list(self.c2_ci),
                "rms": self.rms, "n": self.n, "c2_fixed": self.c2_fixed}


@dataclass(frozen=True)
class ScorFit:
    """Eq. 13 fitted to per-(body, angle) rates.

    ``k1``, ``k2``, ``k3`` of c1 = k1·(b/h) + k2·r + k3 [rad, rad/m, rad] and ``c2`` [-], with 95 %
    confidence intervals in ``ci`` (keys "k1", "k2", "k3" and "c2" when c2 was free). ``body_errors``
    maps (b, h) [m] to that body's Eq. 12 error (fraction) between its observed rates and the fit.
    """

    k1: float
    k2: float
    k3: float
    c2: float
    ci: dict[str, tuple[float, float]]
    rms: float
    n: int
    c2_fixed: bool
    body_errors: dict[tuple[float, float], float] = field(default_factory=dict)

    @property
    def coeffs(self) -> tuple[float, float, float, float]:
        """(k1, k2, k3, c2), as :func:`design_angle` takes them."""
        return (self.k1, self.k2, self.k3, self.c2)

    def as_dict(self) -> dict[str, object]:
        """A JSON-ready dict (body errors as a list of {b, h, error})."""
        return {"k1": self.k1, "k2": self.k2, "k3": self.k3, "c2": self.c2,
                "ci": {k: list(v) for k, v in self.ci.items()}, "rms": self.rms, "n": self.n,
                "c2_fixed": self.c2_fixed,
                "body_errors": [{"b": b, "h": h, "error": e} for (b, h), e in self.body_errors.items()]}


@dataclass(frozen=True)
class _LsqResult:
    params: NDArray[np.float64]
    ci: NDArray[np.float64]  # (p, 2)
    rms: float


def _weights(counts: ArrayLike | None, n: int) -> NDArray[np.float64]:
    if counts is None:
        return np.ones(n)
    w = np.asarray(counts, dtype=float).ravel()
    if w.shape != (n,):
        raise AnalysisInputError(f"counts: expected {n} values, got {w.shape[0]}")
    if np.any(np.isnan(w)) or np.any(w < 0) or np.any(np.isinf(w)):
        raise AnalysisInputError("counts must be finite and ≥ 0")
    return w


def _weighted_lsq(residual, jacobian, x0: Sequence[float], w: NDArray[np.float64], what: str) -> _LsqResult:
    """Minimise Σ w·res² and return the parameters with t-based 95 % CIs from s²·(JᵀWJ)⁻¹."""
    sw = np.sqrt(w)
    sol = optimize.least_squares(lambda p: sw * residual(p), np.asarray(x0, dtype=float),
                                 jac=lambda p: sw[:, None] * jacobian(p), method="lm",
                                 xtol=1e-14, ftol=1e-14, gtol=1e-14, max_nfev=20000)
    n, p = w.size, sol.x.size
    jtj = sol.jac.T @ sol.jac
    if not sol.success or np.linalg.cond(jtj) > 1e14:
        raise AnalysisInputError(f"{what}: the data do not determine the coefficients "
                                 f"(need rates at several inclinations on the rising part of the curve)")
    s2 = 2.0 * sol.cost / (n - p)
    se = np.sqrt(np.diag(np.linalg.inv(jtj)) * s2)
    half = stats.t.ppf(0.5 + CONFIDENCE_LEVEL / 2, n - p) * se
    rms = math.sqrt(2.0 * sol.cost / float(np.sum(w)))
    return _LsqResult(sol.x, np.column_stack([sol.x - half, sol.x + half]), rms)


def _usable(cor: NDArray[np.float64], w: NDArray[np.float64], n_params: int, what: str) -> NDArray[np.bool_]:
    keep = ~np.isnan(cor) & (w > 0)
    n = int(keep.sum())
    if n <= n_params:
        raise AnalysisInputError(f"{what}: {n} usable points (count > 0, COR defined); need more than "
                                 f"{n_params} to fit and give confidence intervals")
    if np.any((cor[keep] < 0) | (cor[keep] > 1)):
        raise AnalysisInputError(f"{what}: COR must be fractions in [0, 1] (0.95 = 95 %)")
    return keep


def fit_gcor(
    angles_rad: ArrayLike, cor: ArrayLike, counts: ArrayLike | None = None, fix_c2: float | None = None
) -> GcorFit:
    """Fit Eq. 11 to rates ``cor`` (fractions) at inclinations ``angles_rad`` [rad].

    ``counts`` (e.g. the number of overturned cases behind each rate) weight the least squares;
    rows with count 0 or a NaN rate are skipped. c2 is free unless ``fix_c2`` is given (the paper:
    0.48); a free fit above 0.5 (COR > 1 at large β) is redone with c2 held at its bound 0.5.
    Starts from the paper's values. Confidence intervals (95 %): standard errors from
    s²·(JᵀWJ)⁻¹ at the solution, s² = Σ w·res² / (n − p), times the t quantile with n − p degrees
    of freedom. ``rms`` is sqrt(Σ w·res² / Σ w).
    """
    beta = np.asarray(angles_rad, dtype=float).ravel()
    y = np.asarray(cor, dtype=float).ravel()
    if beta.shape != y.shape:
        raise AnalysisInputError(f"fit_gcor: {beta.size} angles for {y.size} rates")
    w = _weights(counts, y.size)
    n_params = 1 if fix_c2 is not None else 2
    keep = _usable(y, w, n_params, "fit_gcor")
    if not np.all(np.isfinite(beta[keep])):
        raise AnalysisInputError("fit_gcor: angles must be finite")
    beta, y, w = beta[keep], y[keep], w[keep]

    def unpack(p: NDArray[np.float64]) -> tuple[float, float]:
        return float(p[0]), (float(fix_c2) if fix_c2 is not None else float(p[1]))

    def residual(p: NDArray[np.float64]) -> NDArray[np.float64]:
        c1, c2 = unpack(p)
        return np.tanh(beta / c1) * c2 + 0.5 - y

    def jacobian(p: NDArray[np.float64]) -> NDArray[np.float64]:
        c1, c2 = unpack(p)
        t = np.tanh(beta / c1)
        d_c1 = -c2 * (1 - t**2) * beta / c1**2
        return d_c1[:, None] if fix_c2 is not None else np.column_stack([d_c1, t])

    x0 = [PAPER_GCOR[0]] if fix_c2 is not None else list(PAPER_GCOR)
    res = _weighted_lsq(residual, jacobian, x0, w, "fit_gcor")
    if fix_c2 is None and res.params[0] < 0:  # (c1, c2) and (−c1, −c2) are the same curve
        res = _LsqResult(-res.params, -res.ci[:, ::-1], res.rms)
    if fix_c2 is None and res.params[1] > 0.5:
        # COR cannot exceed 1: a free c2 above 0.5 is held at its bound and c1 fitted alone
        return fit_gcor(angles_rad, cor, counts, fix_c2=0.5)
    c1, c2 = unpack(res.params)
    return GcorFit(c1=c1, c2=c2, c1_ci=(float(res.ci[0, 0]), float(res.ci[0, 1])),
                   c2_ci=None if fix_c2 is not None else (float(res.ci[1, 0]), float(res.ci[1, 1])),
                   rms=res.rms, n=int(y.size), c2_fixed=fix_c2 is not None)


def _scor_rows(rows: NDArray[np.floating] | Iterable[Sequence[float]]) -> NDArray[np.float64]:
    table = np.asarray(list(rows) if not isinstance(rows, np.ndarray) else rows, dtype=float)
    if table.ndim != 2 or table.shape[1] not in (4, 5):
        raise AnalysisInputError(
            f"fit_scor: rows must be (b, h, beta, cor[, count]), got shape {table.shape}"
        )
    if table.shape[1] == 4:
        table = np.column_stack([table, np.ones(len(table))])
    return table


def fit_scor(rows: NDArray[np.floating] | Iterable[Sequence[float]], fix_c2: float | None = PAPER_C2) -> ScorFit:
    """Fit Eq. 13 to per-(body, angle) rows ``(b [m], h [m], β [rad], cor [fraction], count)``.

    Fits k1, k2, k3 of c1 = k1·(b/h) + k2·r + k3 with c2 fixed at ``fix_c2`` (default the paper's
    0.48) or free when ``fix_c2=None``; counts weight the least squares (count 0 or NaN cor: row
    skipped; a 4-column table means unit weights). Starts from the paper's coefficients; CIs as in
    :func:`fit_gcor`. ``body_errors`` gives each body's Eq. 12 error over its rows (unweighted, as in
    the paper's Table III).
    """
    table = _scor_rows(rows)
    b, h, beta, y = (table[:, i] for i in range(4))
    w = _weights(table[:, 4], len(table))
    n_params = 3 if fix_c2 is not None else 4
    keep = _usable(y, w, n_params, "fit_scor")
    b, h, beta, y, w = b[keep], h[keep], beta[keep], y[keep], w[keep]
    _body_b_h((b, h))
    if not np.all(np.isfinite(beta)):
        raise AnalysisInputError("fit_scor: angles must be finite")
    aspect, r = b / h, 0.5 * np.hypot(b, h)
    design = np.column_stack([aspect, r, np.ones_like(r)])

    def unpack(p: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
        c1 = np.maximum(design @ p[:3], 1e-9)  # keeps the trial point finite when a step overshoots
        return c1, (float(fix_c2) if fix_c2 is not None else float(p[3]))

    def residual(p: NDArray[np.float64]) -> NDArray[np.float64]:
        c1, c2 = unpack(p)
        return np.tanh(beta / c1) * c2 + 0.5 - y

    def jacobian(p: NDArray[np.float64]) -> NDArray[np.float64]:
        c1, c2 = unpack(p)
        t = np.tanh(beta / c1)
        d_c1 = -c2 * (1 - t**2) * beta / c1**2
        cols = design * d_c1[:, None]
        return cols if fix_c2 is not None else np.column_stack([cols, t])

    x0 = list(PAPER_SCOR) + ([] if fix_c2 is not None else [PAPER_C2])
    res = _weighted_lsq(residual, jacobian, x0, w, "fit_scor")
    names = ["k1", "k2", "k3"] + ([] if fix_c2 is not None else ["c2"])
    ci = {name: (float(lo), float(hi)) for name, (lo, hi) in zip(names, res.ci, strict=True)}
    k1, k2, k3 = (float(v) for v in res.params[:3])
    c2 = float(fix_c2) if fix_c2 is not None else float(res.params[3])
    fitted = _tanh_curve(beta, np.maximum(design @ res.params[:3], 1e-9), c2)
    body_errors = {
        (float(bb), float(hh)): eq12_error(y[sel], np.asarray(fitted)[sel])
        for bb, hh in sorted({(float(x), float(z)) for x, z in zip(b, h, strict=True)})
        for sel in [(b == bb) & (h == hh)]
    }
    return ScorFit(k1=k1, k2=k2, k3=k3, c2=c2, ci=ci, rms=res.rms, n=int(y.size),
                   c2_fixed=fix_c2 is not None, body_errors=body_errors)


# --------------------------------------------------------------------------------------------------
# The design inverse


@runtime_checkable
class _HasCoeffs(Protocol):
    @property
    def coeffs(self) -> tuple[float, ...]: ...


def design_coefficients(
    body: Body | None, equation: Equation = "SCOR", coeffs: Sequence[float] | _HasCoeffs | None = None
) -> tuple[float, float]:
    """The (c1 [rad], c2) of the curve used for ``body``.

    GCOR: ``coeffs`` = (c1, c2) or a :class:`GcorFit` (default :data:`PAPER_GCOR`); the body is
    ignored. SCOR: ``coeffs`` = (k1, k2, k3), (k1, k2, k3, c2) or a :class:`ScorFit` (default
    :data:`PAPER_SCOR` with c2 = 0.48); c1 from Eq. 13 for the body. No range checks here.
    """
    if isinstance(coeffs, _HasCoeffs):
        values: tuple[float, ...] | None = tuple(coeffs.coeffs)
    else:
        values = None if coeffs is None else tuple(coeffs)
    eq = str(equation).upper()
    if eq == "GCOR":
        values = values if values is not None else PAPER_GCOR
        if len(values) != 2:
            raise AnalysisInputError(f"GCOR coefficients are (c1, c2), got {values!r}")
        return float(values[0]), float(values[1])
    if eq == "SCOR":
        if body is None:
            raise AnalysisInputError("SCOR (Eq. 13) needs the body's b and h")
        values = values if values is not None else (*PAPER_SCOR, PAPER_C2)
        if len(values) not in (3, 4):
            raise AnalysisInputError(f"SCOR coefficients are (k1, k2, k3[, c2]), got {values!r}")
        c2 = values[3] if len(values) == 4 else PAPER_C2
        return float(scor_c1(body, values[:3])), float(c2)
    raise AnalysisInputError(f"equation must be 'SCOR' or 'GCOR', got {equation!r}")


def design_angle(
    body: Body | None, confidence: float, equation: Equation = "SCOR",
    coeffs: Sequence[float] | _HasCoeffs | None = None,
) -> float:
    """The smallest inclination β [rad] whose controlled-overturning rate reaches ``confidence``.

    Inverts Eq. 11 (``equation="GCOR"``) or Eq. 13 (``"SCOR"``, the default, body-specific) in
    closed form: ``β = c1·atanh((confidence − 0.5)/c2)``; the curve is increasing, so this is the
    smallest β with COR(β) ≥ confidence. ``confidence`` is a fraction. Coefficients as in
    :func:`design_coefficients`. Raises :class:`AnalysisInputError` when confidence ≤ 0.5 (the rate
    at β = 0: nothing to design), ≥ 0.5 + c2 (the curve's upper limit, 0.98 with the paper's c2:
    unreachable at any angle), or when c1 ≤ 0 (Eq. 13 extrapolated beyond its bodies).
    """
    c1, c2 = design_coefficients(body, equation, coeffs)
    eq = str(equation).upper()
    if not (isinstance(confidence, int | float) and math.isfinite(confidence)):
        raise AnalysisInputError(f"confidence must be a finite fraction, got {confidence!r}")
    if confidence > 1:
        raise AnalysisInputError(f"confidence is a fraction in (0.5, 1) (0.95 = 95 %), got {confidence:g}")
    if not (math.isfinite(c1) and c1 > 0):
        where = f" for body {_describe(body)} (c1 = k1·b/h + k2·r + k3)" if eq == "SCOR" else ""
        raise AnalysisInputError(f"{eq} c1 = {c1:.4g} rad ≤ 0{where}: the equation does not apply")
    if not (math.isfinite(c2) and 0 < c2 <= 0.5):
        raise AnalysisInputError(f"{eq} c2 must be in (0, 0.5], got {c2:g}")
    if confidence <= 0.5:
        raise AnalysisInputError(f"confidence must exceed 0.5, the controlled-overturning rate on a level "
                                 f"plate (β = 0); got {confidence:g}")
    limit = 0.5 + c2
    if confidence >= limit:
        raise AnalysisInputError(f"confidence {confidence:g} is unreachable: {eq} approaches but never "
                                 f"reaches 0.5 + c2 = {limit:g} at any inclination")
    return c1 * math.atanh((confidence - 0.5) / c2)
