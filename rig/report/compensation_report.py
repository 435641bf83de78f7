"""The report's drive-compensation section (a session written by ``rig iterate``: its ``/compensation`` group,
``rig.compensation.store``): the measured frequency response per axis (magnitude, phase, coherence), the fall-line
error per iteration, and the target against the achieved fall-line acceleration with their 5 % response spectra
before (the drive as prepared) and after (the best iteration)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from analysis.spectrum import DAMPING, DEFAULT_PERIODS, pseudo_acceleration_spectrum
from rig.compensation import store as compensation_store

from . import figures
from .html import esc, figure, key_values, num, table

AXES = ("surge", "lateral", "heave")


def _response_png(rows: np.ndarray, band: tuple[float, float]) -> bytes:
    f = rows["f"]
    inside = (f >= band[0]) & (f <= band[1])
    with figures._figure(4.2, nrows=3, sharex=True) as (fig, axes):
        mag, phase, coh = axes[:, 0]
        for k, axis in enumerate(AXES):
            h = rows[f"{axis}_h_re"][inside] + 1j * rows[f"{axis}_h_im"][inside]
            if not np.any(h):
                continue
            mag.plot(f[inside], np.abs(h), color=f"C{k}", label=axis)
            phase.plot(f[inside], np.degrees(np.unwrap(np.angle(h))), color=f"C{k}")
            coh.plot(f[inside], rows[f"{axis}_coherence"][inside], color=f"C{k}")
        mag.set_xscale("log")
        mag.set_ylabel("|H| [-]")
        phase.set_ylabel("phase [°]")
        coh.set_ylabel("coherence γ² [-]")
        coh.set_ylim(0, 1.05)
        coh.set_xlabel("frequency [Hz]")
        mag.legend(loc="upper left", ncols=3, frameon=False)
        fig.subplots_adjust(left=0.09, right=0.99, bottom=0.1, top=0.98, hspace=0.12)
        return figures.png(fig)


def _errors_png(rows: np.ndarray) -> bytes:
    with figures._figure(2.0) as (fig, axes):
        ax = axes[0, 0]
        ax.plot(rows["index"], rows["rms_error_pct"], "o-", color="C0", label="RMS error")
        ax.plot(rows["index"], rows["peak_error_pct"], "s--", color="C3", label="peak error")
        ax.axhline(5.0, color="0.4", ls=":", lw=0.8)
        ax.set_xlabel("play (0: drive as prepared, at the ramp's first level)")
        ax.set_ylabel("fall-line error [%]")
        ax.set_xticks(rows["index"])
        ax.legend(frameon=False)
        fig.subplots_adjust(left=0.09, right=0.99, bottom=0.22, top=0.96)
        return figures.png(fig)


def _history_png(t: np.ndarray, target: np.ndarray, before: np.ndarray, after: np.ndarray, best: int) -> bytes:
    dt = float(np.median(np.diff(t)))
    spectra = [pseudo_acceleration_spectrum(a, dt, DEFAULT_PERIODS) for a in (target, before, after)]
    with figures._figure(4.0, ncols=2, nrows=2, gridspec_kw={"width_ratios": [1.65, 1.0]}) as (fig, axes):
        for row, (achieved, label) in enumerate(((before, "as prepared (iteration 0)"),
                                                 (after, f"compensated (iteration {best})"))):
            ax, sp = axes[row]
            ax.plot(*figures.envelope(t, target), color="C0", label="target")
            ax.plot(*figures.envelope(t, achieved), color="C3", alpha=0.75, lw=0.7, label=f"achieved, {label}")
            ax.set_ylabel("fall-line acc. [m/s²]")
            ax.legend(loc="lower right", bbox_to_anchor=(1.0, 1.0), ncols=2, frameon=False, borderaxespad=0.1)
            sp.plot(DEFAULT_PERIODS, spectra[0], color="C0", label="target")
            sp.plot(DEFAULT_PERIODS, spectra[1 + row], color="C3", label="achieved")
            sp.set_xscale("log")
            sp.set_ylabel(f"PSA {DAMPING * 100:g} % [m/s²]")
        axes[1, 0].set_xlabel("time [s]")
        axes[1, 1].set_xlabel("period [s]")
        fig.subplots_adjust(left=0.08, right=0.99, bottom=0.1, top=0.93, wspace=0.28, hspace=0.4)
        return figures.png(fig)


def _cell(row: np.void, name: str, fmt: str) -> str:
    """A number of an iteration row, "–" in a session written before it was stored (compensation/1)."""
    return num(row[name], fmt) if name in (row.dtype.names or ()) else "–"


def compensation_section(path: Any) -> str:
    """The section's HTML, or "" when the session has no ``/compensation`` group."""
    stored = compensation_store.read(path)
    if stored is None:
        return ""
    attrs, response, rows = stored["attrs"], stored["response"], stored["iterations"]
    t, target, achieved = stored["t"], stored["target"], stored["achieved"]
    low, high = (float(x) for x in attrs.get("band_hz", (0.0, math.inf)))
    band = (low, high)
    best = int(attrs.get("best", 0))
    parts = ["<h2>Drive compensation</h2>", key_values([
        ("record", esc(attrs.get("record"))), ("plate angle", f"{num(attrs.get('angle_deg'), 'g')}°"),
        ("identification run", esc(attrs.get("identification_run"))),
        ("update law", esc(attrs.get("law", "diagonal"))),
        ("plays", f"{len(rows)} ({len(rows) - 1} correction(s)); best: play {best}"),
        ("converged", f"{bool(attrs.get('converged'))} ({esc(attrs.get('stopped'))})"),
        ("compensated drive", esc(attrs.get("drive_file")))])]
    parts.append(figure(_response_png(response, band), (
        f"The table's measured frequency response (identification run, re-estimated with every play under the mimo "
        f"law): H1 from commanded to measured base-frame acceleration, its direct term per axis, magnitude, phase and "
        f"coherence γ² (multiple coherence under the mimo law), {band[0]:g}–{band[1]:g} Hz."),
        alt="frequency response"))
    parts.append(table(["play", "run", "level [dB]", "RMS error [%]", "noise floor [%]", "peak error [%]", "TRAC",
                        "5 % PSA error max / mean [%]", "RMS error surge / lateral / heave [%]", "peak / limit",
                        "gain", "time [s]"], [
        [int(r["index"]), r["run"].decode(), _cell(r, "level_db", "g"), num(r["rms_error_pct"], ".2f"),
         _cell(r, "noise_floor_pct", ".2f"), num(r["peak_error_pct"], ".1f"), _cell(r, "fall_line_trac", ".4f"),
         f"{_cell(r, 'psa_error_max_pct', '.1f')} / {_cell(r, 'psa_error_mean_pct', '.1f')}",
         " / ".join(_cell(r, f"{axis}_rms_error_pct", ".1f") for axis in AXES), _cell(r, "peak_to_limit", ".2f"),
         num(r["gain"], "g"), num(r["seconds"], ".1f")] for r in rows],
        caption="Error per play (the first ones ramp up in level): fall-line RMS(achieved − target)/RMS(target) and "
                "max|achieved − target|/max|target| over the record's motion, the accelerometer's noise floor (its "
                "RMS while the plate is still before the motion, of the target's RMS: no play can do better), the time "
                "response assurance criterion (tᵀa)²/((tᵀt)(aᵀa)), the 5 % damped response spectrum's largest and mean "
                "error over the compensated band, the RMS error per axis (of the fall line's RMS on an axis the record "
                "leaves at rest), the largest acceleration against its Table IV limit (docs/compensation.md)", left=2))
    parts.append(figure(_errors_png(rows), "Fall-line RMS and peak error per iteration [%]; dotted: 5 %.",
                        alt="error per iteration"))
    if len(achieved):
        parts.append(figure(_history_png(t, target, achieved[0], achieved[best], best), (
            "Target (the drive's fall-line acceleration as prepared) against the achieved fall-line acceleration "
            f"[m/s²], before and after compensation, with their {DAMPING * 100:g} % damped pseudo-acceleration "
            "spectra."), alt="target against achieved acceleration"))
    return "\n".join(parts)
