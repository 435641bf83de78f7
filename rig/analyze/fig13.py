"""The paper's Fig. 13: controlled overturning rate per angle, analytical against experimental.

One case is one body on the plate in one completed run: the analysis's predicted direction (per model) and the
experiment's observed one (+1 low side, −1 high side, 0 did not overturn; docs/architecture.md §2). Per side,

    COR = #(direction = +1) / #(direction ≠ 0)

a case that did not overturn entering neither count of that side; NaN (``null`` in JSON) with no overturn. Rows per
model, angle and body (``body_id`` ≥ 1) and an average row per model and angle (``body_id = 0``): counts, ``runs``,
``records``, both CORs with their 95 % intervals (``*_low``, ``*_high``),
``difference = cor_analysis − cor_experiment`` (a fraction, not percent) with its 90 % interval, the equivalence
``verdict`` within ``margin`` (default 5 points) with its p-values and ``runs_to_resolve``, and McNemar's paired
counts and p-values; ``max_difference`` per model. Cases are clustered by record (``Case.record``).
:func:`rule_label` and :func:`side_by_side` put a model's impact rules together (``rig analyze --restitution all``).

What each field means and which estimator gives it (Wilson, the cluster bootstrap, Miettinen–Nurminen TOST,
McNemar's exact test): docs/fig13.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from analysis.agreement import (
    ALPHA,
    DIFFERENT,
    EQUIVALENT,
    MARGIN,
    NOT_RESOLVED,
    UNDEFINED,
    Verdict,
    equivalence,
    mcnemar_exact,
)
from analysis.proportions import (
    BOOTSTRAP_SEED,
    MIN_BOOTSTRAP_RECORDS,
    cluster_resamples,
    degenerate,
    mean_rate,
    percentile_interval,
    wilson_interval,
)

#: Compound layout of the ``/analysis/fig13`` dataset.
FIG13_DTYPE = np.dtype([
    ("angle_deg", "<f8"), ("body_id", "<i4"), ("model", "S16"), ("runs", "<i4"), ("records", "<i4"),
    ("overturned_analysis", "<i4"), ("towards_low_analysis", "<i4"), ("cor_analysis", "<f8"),
    ("overturned_experiment", "<i4"), ("towards_low_experiment", "<i4"), ("cor_experiment", "<f8"),
    ("difference", "<f8"), ("cor_analysis_low", "<f8"), ("cor_analysis_high", "<f8"),
    ("cor_experiment_low", "<f8"), ("cor_experiment_high", "<f8"),
    ("difference_low", "<f8"), ("difference_high", "<f8"), ("verdict", "S16"), ("p_equivalent", "<f8"),
    ("p_different", "<f8"), ("runs_to_resolve", "<i4"), ("margin", "<f8"),
    ("both_overturned", "<i4"), ("low_high", "<i4"), ("high_low", "<i4"), ("p_direction", "<f8"),
    ("analysis_only", "<i4"), ("experiment_only", "<i4"), ("p_overturn", "<f8"),
])

ANGLE_DIGITS = 6
"""Angles are grouped after rounding to this many decimals of a degree."""

VERDICTS = (EQUIVALENT, DIFFERENT, NOT_RESOLVED, UNDEFINED)
"""The equivalence verdicts, in the order they are counted."""


@dataclass(frozen=True)
class Case:
    """One body in one run for one model: angle [deg], body, model, predicted and observed direction, and the
    record played (its name without polarity: the cluster of the bootstrap; empty: a record of its own)."""

    angle_deg: float
    body_id: int
    model: str
    predicted: int
    observed: int
    record: str = ""


@dataclass(frozen=True)
class Fig13Row:
    """One row of the comparison (module docstring); rates and differences are fractions, NaN when undefined."""

    angle_deg: float
    body_id: int
    model: str
    runs: int
    records: int
    overturned_analysis: int
    towards_low_analysis: int
    cor_analysis: float
    overturned_experiment: int
    towards_low_experiment: int
    cor_experiment: float
    difference: float
    cor_analysis_low: float
    cor_analysis_high: float
    cor_experiment_low: float
    cor_experiment_high: float
    difference_low: float
    difference_high: float
    verdict: str
    p_equivalent: float
    p_different: float
    runs_to_resolve: int
    """With ``not resolved``: the ``runs`` (for the average row body-runs) at which the same rates would resolve it;
    −1 none would; 0 for another verdict."""
    margin: float
    both_overturned: int
    low_high: int
    high_low: int
    p_direction: float
    analysis_only: int
    experiment_only: int
    p_overturn: float

    def verdict_words(self) -> str:
        """The verdict as `rig analyze` and the report print it (`verdict_words`)."""
        return verdict_words(self.verdict, self.body_id, self.runs, self.runs_to_resolve)

    def to_json(self) -> dict:
        """JSON-ready (NaN → None)."""
        return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in asdict(self).items()}


def rule_label(model: str, rule: str) -> str:
    """The label of ``model`` run under impact ``rule`` (``rig analyze --restitution all``): ``"rocking:fit"``."""
    return f"{model}:{rule}"


def split_label(label: str) -> tuple[str, str]:
    """(model, rule) of a :func:`rule_label`; a plain model name gives (model, "")."""
    model, _, rule = label.partition(":")
    return model, rule


def side_by_side(rows: Iterable[Mapping[str, Any]]) -> list[tuple[str, float, int, dict[str, Mapping[str, Any]]]]:
    """The rows (`Fig13Row.to_json` or the stored ``fig13`` records) of models run under several impact rules,
    grouped: (model, angle_deg, body_id, {rule: row}) per model, angle and body, in the order first seen (rows
    of a plain model name go under rule "")."""
    out: dict[tuple[str, float, int], dict[str, Mapping[str, Any]]] = {}
    for row in rows:
        model, rule = split_label(str(row["model"]))
        key = (model, round(float(row["angle_deg"]), ANGLE_DIGITS), int(row["body_id"]))
        out.setdefault(key, {})[rule] = row
    return [(model, angle, body_id, by_rule) for (model, angle, body_id), by_rule in out.items()]


def verdict_words(verdict: str, body_id: int, runs: int, runs_to_resolve: int) -> str:
    """A row's verdict in words, e.g. ``not resolved with 26 runs (about 410 would)``."""
    if verdict != NOT_RESOLVED:
        return verdict
    unit = "body-runs" if body_id == 0 else "runs"
    more = f"no number of {unit} would" if runs_to_resolve < 0 else f"about {runs_to_resolve} would"
    return f"not resolved with {runs} {unit} ({more})"


def cor(towards_low: int, overturned: int) -> float:
    """towards_low / overturned, NaN when nothing overturned."""
    return towards_low / overturned if overturned else math.nan


@dataclass(frozen=True)
class _Counts:
    """One model at one angle: per body (rows) and record (columns) the four counts, and the pairs per body."""

    bodies: list[int]
    records: int
    low_a: np.ndarray
    over_a: np.ndarray
    low_e: np.ndarray
    over_e: np.ndarray
    runs: np.ndarray
    pairs: list[list[Case]]


def _counts(cases: list[Case]) -> _Counts:
    bodies = sorted({c.body_id for c in cases})
    keys: dict[str, int] = {}
    for k, c in enumerate(cases):
        keys.setdefault(c.record or f"\x00case {k}", len(keys))
    shape = (len(bodies), len(keys))
    low_a, over_a, low_e, over_e, runs = (np.zeros(shape, dtype=np.int64) for _ in range(5))
    pairs: list[list[Case]] = [[] for _ in bodies]
    for k, c in enumerate(cases):
        j, r = bodies.index(c.body_id), keys[c.record or f"\x00case {k}"]
        runs[j, r] += 1
        over_a[j, r] += c.predicted != 0
        low_a[j, r] += c.predicted == 1
        over_e[j, r] += c.observed != 0
        low_e[j, r] += c.observed == 1
        pairs[j].append(c)
    return _Counts(bodies, len(keys), low_a, over_a, low_e, over_e, runs, pairs)


def fig13_rows(cases: Iterable[Case], margin: float = MARGIN, seed: int = BOOTSTRAP_SEED) -> list[Fig13Row]:
    """The comparison rows, ordered by model (first seen), angle, then body (average row first); ``margin``
    [fraction] of the equivalence test, ``seed`` of the cluster bootstrap."""
    groups: dict[tuple[str, float], list[Case]] = {}
    for case in cases:
        groups.setdefault((case.model, round(case.angle_deg, ANGLE_DIGITS)), []).append(case)
    models = list(dict.fromkeys(model for model, _ in groups))
    rows: list[Fig13Row] = []
    for model in models:
        for angle in sorted(a for m, a in groups if m == model):
            counts = _counts(groups[(model, angle)])
            weights = cluster_resamples(counts.records, seed=seed)
            rows.append(_row(angle, 0, model, counts, range(len(counts.bodies)), weights, margin))
            rows.extend(_row(angle, body, model, counts, [j], weights, margin)
                        for j, body in enumerate(counts.bodies))
    return rows


def _row(angle: float, body_id: int, model: str, counts: _Counts, members: Iterable[int], weights: np.ndarray,
         margin: float) -> Fig13Row:
    """The average row (``body_id`` 0, over ``members``) or one body's row."""
    sel = list(members)
    low_a, over_a = counts.low_a[sel], counts.over_a[sel]
    low_e, over_e = counts.low_e[sel], counts.over_e[sel]
    runs = int(counts.runs[sel].sum())
    records = int(np.count_nonzero(counts.runs[sel].sum(axis=0)))
    independent = body_id != 0 and int(over_a.max(initial=0)) <= 1 and int(over_e.max(initial=0)) <= 1
    if independent:
        cor_a, cor_e = cor(int(low_a.sum()), int(over_a.sum())), cor(int(low_e.sum()), int(over_e.sum()))
        interval_a = wilson_interval(int(low_a.sum()), int(over_a.sum()))
        interval_e = wilson_interval(int(low_e.sum()), int(over_e.sum()))
        verdict = equivalence(int(low_a.sum()), int(over_a.sum()), int(low_e.sum()), int(over_e.sum()), margin,
                              cases=runs)
    else:
        ones = np.ones((1, counts.records))
        cor_a, cor_e = float(mean_rate(low_a, over_a, ones)[0]), float(mean_rate(low_e, over_e, ones)[0])
        boot_a, boot_e = mean_rate(low_a, over_a, weights), mean_rate(low_e, over_e, weights)
        few = records < MIN_BOOTSTRAP_RECORDS
        interval_a = _interval(boot_a, cor_a, over_a, few)
        interval_e = _interval(boot_e, cor_e, over_e, few)
        verdict = _bootstrap_verdict(cor_a, cor_e, boot_a - boot_e, over_a, over_e, runs, margin, few)
    pairs = [c for j in sel for c in counts.pairs[j]]
    both = [c for c in pairs if c.predicted and c.observed]
    low_high = sum(1 for c in both if c.predicted == 1 and c.observed == -1)
    high_low = sum(1 for c in both if c.predicted == -1 and c.observed == 1)
    only_a = sum(1 for c in pairs if c.predicted and not c.observed)
    only_e = sum(1 for c in pairs if c.observed and not c.predicted)
    paired = body_id != 0
    return Fig13Row(
        angle, body_id, model, runs, records, int(over_a.sum()), int(low_a.sum()), cor_a, int(over_e.sum()),
        int(low_e.sum()), cor_e, cor_a - cor_e, *interval_a, *interval_e, verdict.low, verdict.high,
        verdict.verdict, verdict.p_equivalent, verdict.p_different,
        (-1 if verdict.cases_to_resolve is None else verdict.cases_to_resolve)
        if verdict.verdict == NOT_RESOLVED else 0, margin,
        len(both), low_high, high_low, mcnemar_exact(low_high, high_low) if paired else math.nan,
        only_a, only_e, mcnemar_exact(only_a, only_e) if paired else math.nan)


def _records_once(rate: float, over: np.ndarray) -> tuple[float, int]:
    """(k, n): each record that had an overturn counted as one case, k = ``rate`` · n (fractional where the rate
    is, e.g. a record whose two polarities fell to either side)."""
    n = int(np.count_nonzero(over.sum(axis=0)))
    return rate * n, n


def _interval(samples: np.ndarray, rate: float, over: np.ndarray, few: bool) -> tuple[float, float]:
    """The 95 % percentile interval of the resampled rate; Wilson's with each record once if the resamples do not
    vary or the records are ``few``."""
    if math.isnan(rate):
        return math.nan, math.nan
    if few or degenerate(samples):
        return wilson_interval(*_records_once(rate, over))
    return percentile_interval(samples)


def _bootstrap_verdict(cor_a: float, cor_e: float, samples: np.ndarray, over_a: np.ndarray, over_e: np.ndarray,
                       runs: int, margin: float, few: bool) -> Verdict:
    """TOST on the cluster-bootstrap distribution of the difference (module docstring); the score TOST with each
    record counted once where the resamples do not vary or the records are ``few``."""
    if math.isnan(cor_a) or math.isnan(cor_e):
        return Verdict(UNDEFINED, math.nan, math.nan, math.nan, math.nan, math.nan, margin, runs)
    d = cor_a - cor_e
    if few or degenerate(samples):
        (k1, n1), (k2, n2) = _records_once(cor_a, over_a), _records_once(cor_e, over_e)
        return equivalence(k1, n1, k2, n2, margin, cases=runs, overturn_fractions=(n1 / runs, n2 / runs))
    finite = samples[np.isfinite(samples)]
    low, high = percentile_interval(finite, 1.0 - 2.0 * ALPHA)
    p_low, p_high = float(np.mean(finite <= -margin)), float(np.mean(finite >= margin))
    p_beyond = float(np.mean(finite <= margin)) if d >= 0 else float(np.mean(finite >= -margin))
    if max(p_low, p_high) < ALPHA:
        kind = EQUIVALENT
    elif p_beyond < ALPHA:
        kind = DIFFERENT
    else:
        kind = NOT_RESOLVED
    needed = _runs_to_resolve(d, low, high, margin, runs) if kind == NOT_RESOLVED else None
    return Verdict(kind, d, low, high, max(p_low, p_high), p_beyond, margin, runs, needed)


def _runs_to_resolve(d: float, low: float, high: float, margin: float, runs: int) -> int | None:
    """The runs at which the bootstrap interval, narrowing as 1/√runs about ``d``, would lie inside ±margin (|d| <
    margin) or beyond it; None for a difference at the margin."""
    if abs(d) < margin:
        factor = max(((high - d) / (margin - d)) ** 2, ((d - low) / (margin + d)) ** 2)
    elif abs(d) > margin:
        factor = ((d - low) / (d - margin)) ** 2 if d > 0 else ((high - d) / (-margin - d)) ** 2
    else:
        return None
    return max(runs + 1, math.ceil(runs * factor))


def max_difference(rows: Iterable[Fig13Row]) -> dict[str, float | None]:
    """Per model, the largest |difference| over the per-body rows (None when no difference is defined)."""
    out: dict[str, float | None] = {}
    for row in rows:
        out.setdefault(row.model, None)
        if row.body_id == 0 or math.isnan(row.difference):
            continue
        current = out[row.model]
        out[row.model] = abs(row.difference) if current is None else max(current, abs(row.difference))
    return out


def verdict_counts(rows: Iterable[Fig13Row]) -> dict[str, dict[str, int]]:
    """Per model, how many per-body rows got each verdict (:data:`VERDICTS`)."""
    out: dict[str, dict[str, int]] = {}
    for row in rows:
        counts = out.setdefault(row.model, dict.fromkeys(VERDICTS, 0))
        if row.body_id != 0:
            counts[row.verdict] += 1
    return out


def to_array(rows: list[Fig13Row]) -> np.ndarray:
    """The rows as a `FIG13_DTYPE` array (for the session file)."""
    out = np.zeros(len(rows), dtype=FIG13_DTYPE)
    names = FIG13_DTYPE.names
    assert names is not None  # a structured dtype
    for i, row in enumerate(rows):
        values = asdict(row)
        values["model"] = row.model.encode("utf-8")
        values["verdict"] = row.verdict.encode("utf-8")
        out[i] = tuple(values[name] for name in names)
    return out
