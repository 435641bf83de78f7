"""The report's figures, drawn with matplotlib's Agg renderer (no pyplot, no display) into PNG bytes.

**PNG, not SVG.** A run's time history has ~60 000 samples per curve: as SVG that is a path of that many vertices
(or, decimated, still tens of kB per curve plus the glyphs), and a 125-run campaign's report would grow with the
sampling rate. A raster's size depends only on its pixel count: 170 mm wide at 120 dpi (~800 px, sharp at A4
print size and on screen), quantized to a 256-colour palette (Pillow), a run figure is ~30–60 kB, base64-embedded
in an ``<img>`` (+33 %). Browsers decode PNG everywhere with nothing to run, and a screenshot check can tell an
empty image from a drawn one. Curves longer than `MAX_POINTS` are drawn from their min/max envelope per bin, which
keeps every peak.

Every axis is labelled with its unit.
"""

from __future__ import annotations

import io
import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib import rc_context
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.typing import RcKeyType
from numpy.typing import NDArray
from PIL import Image

from analysis.body import G

WIDTH_IN = 6.7
"""Figure width [in]: 170 mm, the text width of an A4 page with 20 mm margins."""
DPI = 120
"""Raster resolution [dots per inch]."""
MAX_POINTS = 4000
"""Curves with more samples are drawn from their per-bin min/max envelope (2 points per bin)."""
COMMANDED_COLOR = "#1f3a93"
"""The commanded traces' colour (dark blue), drawn over the measured ones (red)."""

_STYLE: dict[RcKeyType, Any] = {
    "font.size": 8, "axes.titlesize": 8, "axes.labelsize": 8, "legend.fontsize": 7, "xtick.labelsize": 7,
    "ytick.labelsize": 7, "lines.linewidth": 0.9, "axes.grid": True, "grid.alpha": 0.3,
    "savefig.facecolor": "white", "figure.facecolor": "white"}


@contextmanager
def _figure(height_in: float, ncols: int = 1, nrows: int = 1, *, sharex: bool = False, sharey: bool = False,
            gridspec_kw: dict[str, Any] | None = None) -> Iterator[tuple[Figure, np.ndarray]]:
    with rc_context(_STYLE):
        fig = Figure(figsize=(WIDTH_IN, height_in), dpi=DPI)
        FigureCanvasAgg(fig)
        axes = fig.subplots(nrows, ncols, squeeze=False, sharex=sharex, sharey=sharey, gridspec_kw=gridspec_kw)
        yield fig, axes


def png(fig: Figure) -> bytes:
    """The figure as a palette PNG (256 colours) [bytes]."""
    canvas = fig.canvas
    assert isinstance(canvas, FigureCanvasAgg)
    canvas.draw()
    image = Image.frombuffer("RGBA", canvas.get_width_height(), canvas.buffer_rgba(), "raw", "RGBA", 0, 1)
    image = image.convert("RGB").quantize(256, method=Image.Quantize.FASTOCTREE)
    out = io.BytesIO()
    image.save(out, format="PNG", optimize=False, compress_level=6, dpi=(DPI, DPI))
    return out.getvalue()


def envelope(t: NDArray[np.float64], y: NDArray[np.float64],
             max_points: int = MAX_POINTS) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(t, y)`` reduced to at most ``max_points`` points: per bin of consecutive samples its minimum and its
    maximum, in time order (what a line of that many samples looks like at the figure's resolution)."""
    n = y.size
    if n <= max_points:
        return t, y
    bins = max_points // 2
    size = n // bins
    m = bins * size
    yb = y[:m].reshape(bins, size)
    tb = t[:m].reshape(bins, size)
    lo, hi = yb.argmin(axis=1), yb.argmax(axis=1)
    first = np.minimum(lo, hi)
    second = np.maximum(lo, hi)
    rows = np.arange(bins)
    tt = np.column_stack([tb[rows, first], tb[rows, second]]).ravel()
    yy = np.column_stack([yb[rows, first], yb[rows, second]]).ravel()
    return np.append(tt, t[m:]), np.append(yy, y[m:])


@dataclass(frozen=True)
class Mark:
    """A detection drawn on a time history: time [s] and its label."""

    t: float
    label: str


class RunFigure:
    """The figure of one run, built once and redrawn for each run of a session (a new matplotlib figure per run
    costs about twice as much: axes, ticks and legends are made anew): (a) commanded and measured horizontal
    acceleration [m/s²] against time [s], detections as dotted vertical lines; (b) their 5 % damped
    pseudo-acceleration spectra [m/s²] against period [s]."""

    def __init__(self, periods: NDArray[np.float64]) -> None:
        with rc_context(_STYLE):
            self.fig = Figure(figsize=(WIDTH_IN, 2.6), dpi=DPI)
            FigureCanvasAgg(self.fig)
            self.ax, self.sp = self.fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.65, 1.0]})
            # the commanded trace is drawn over the measured one (thin and dark): it stays visible where the table
            # follows it closely, and the measured one shows around it where it does not
            self.meas, = self.ax.plot([], [], color="C3", alpha=0.75, lw=1.1, label="measured", zorder=2)
            self.cmd, = self.ax.plot([], [], color=COMMANDED_COLOR, lw=0.6, label="commanded", zorder=3)
            self.ax.set_xlabel("time [s]")
            self.ax.set_ylabel("horizontal acceleration [m/s²]")
            self.ax.set_title("(a) acceleration", loc="left")
            self.periods = np.asarray(periods, dtype=float)
            self.psa_meas, = self.sp.plot(self.periods, np.zeros_like(self.periods), color="C3", lw=1.4,
                                          label="measured", zorder=2)
            self.psa_cmd, = self.sp.plot(self.periods, np.zeros_like(self.periods), color=COMMANDED_COLOR, lw=0.8,
                                         label="commanded", zorder=3)
            self.sp.set_xscale("log")
            self.sp.set_xlabel("period [s]")
            self.sp.set_ylabel("PSA, 5 % damping [m/s²]")
            self.sp.set_title("(b) response spectrum", loc="left")
            self.ax.legend(handles=[self.cmd, self.meas], loc="lower right", bbox_to_anchor=(1.0, 1.0), ncols=2,
                           frameon=False, borderaxespad=0.1)
            self.fig.subplots_adjust(left=0.08, right=0.99, bottom=0.16, top=0.9, wspace=0.28)
        self._marks: list[Artist] = []

    def render(self, t_cmd: NDArray[np.float64], a_cmd: NDArray[np.float64], t_meas: NDArray[np.float64],
               a_meas: NDArray[np.float64], psa_cmd: NDArray[np.float64] | None,
               psa_meas: NDArray[np.float64] | None, marks: Sequence[Mark] = ()) -> bytes:
        """The PNG of one run (spectra at the periods given to the constructor; None: not drawn)."""
        with rc_context(_STYLE):
            for artist in self._marks:
                artist.remove()
            self._marks = []
            self.cmd.set_data(*envelope(t_cmd, a_cmd))
            self.meas.set_data(*envelope(t_meas, a_meas))
            for k, mark in enumerate(sorted(marks, key=lambda m: m.t)):
                self._marks.append(self.ax.axvline(mark.t, color="k", ls=":", lw=0.8))
                self._marks.append(self.ax.annotate(
                    mark.label, (mark.t, 1.0), xycoords=("data", "axes fraction"), xytext=(2, -9 - 8 * (k % 4)),
                    textcoords="offset points", fontsize=6.5))
            for line, psa in ((self.psa_cmd, psa_cmd), (self.psa_meas, psa_meas)):
                line.set_visible(psa is not None)
                line.set_ydata(np.zeros_like(self.periods) if psa is None else psa)
            for axes in (self.ax, self.sp):
                axes.relim(visible_only=True)
                axes.autoscale_view()
            return png(self.fig)


class TrackingFigure:
    """How the table followed a run's drive, built once and redrawn for each run (as :class:`RunFigure`):
    (c) the fall-line acceleration error measured − commanded [m/s²] against time [s], its RMS and peak in the
    legend; (d) the legs' lengths [m] with their stroke limits (dashed); (e) the plate's translations [mm] and
    (f) rotations [°], measured (solid) and commanded (thin, dark)."""

    AXES = ("surge", "sway", "heave", "roll", "pitch", "yaw")

    def __init__(self) -> None:
        with rc_context(_STYLE):
            self.fig = Figure(figsize=(WIDTH_IN, 4.4), dpi=DPI)
            FigureCanvasAgg(self.fig)
            (self.err_ax, self.leg_ax), (self.trans_ax, self.rot_ax) = self.fig.subplots(2, 2)
            self.err, = self.err_ax.plot([], [], color="C3", lw=0.7, label="error")
            self.err_ax.axhline(0.0, color="0.4", lw=0.6)
            self.err_ax.set_ylabel("fall-line error [m/s²]")
            self.err_ax.set_title("(c) measured − commanded fall-line acceleration", loc="left")
            self.legs = [self.leg_ax.plot([], [], color=f"C{k}", lw=0.8, label=f"leg {k + 1}")[0] for k in range(6)]
            self.limits = [self.leg_ax.axhline(0.0, color="k", ls="--", lw=0.7) for _ in range(2)]
            self.leg_ax.set_ylabel("leg length [m]")
            self.leg_ax.set_title("(d) legs against their stroke limits (dashed)", loc="left")
            self.leg_ax.legend(loc="center right", ncols=2, fontsize=6)
            self.pose: dict[str, tuple[Line2D, Line2D]] = {}
            for k, axis in enumerate(self.AXES):
                ax = self.trans_ax if k < 3 else self.rot_ax
                measured, = ax.plot([], [], color=f"C{k % 3}", lw=1.0, label=axis, zorder=2)
                commanded, = ax.plot([], [], color=COMMANDED_COLOR, lw=0.5, zorder=3)
                self.pose[axis] = (measured, commanded)
            self.trans_ax.set_ylabel("translation [mm]")
            self.trans_ax.set_title("(e) plate translations (thin dark: commanded)", loc="left")
            self.rot_ax.set_ylabel("rotation [°]")
            self.rot_ax.set_title("(f) plate rotations (thin dark: commanded)", loc="left")
            for ax in (self.trans_ax, self.rot_ax):
                ax.set_xlabel("time [s]")
                ax.legend(loc="upper right", ncols=3, fontsize=6)
            self.fig.subplots_adjust(left=0.09, right=0.99, bottom=0.09, top=0.94, wspace=0.28, hspace=0.42)

    def render(self, error: tuple[NDArray[np.float64], NDArray[np.float64], float, float] | None,
               legs: tuple[NDArray[np.float64], NDArray[np.float64], float, float] | None,
               pose: NDArray[np.float64], commanded: NDArray[np.float64]) -> bytes:
        """The PNG: ``error`` (t [s], error [m/s²], RMS, peak [m/s²]) or None, ``legs`` (t [s], lengths (K, 6) [m],
        leg_min, leg_max [m]) or None, the measured ``pose`` and ``commanded`` rows (t, surge, sway, heave [m],
        roll, pitch, yaw [rad])."""
        with rc_context(_STYLE):
            if error is None:
                self.err.set_data([], [])
                self.err.set_label("error: no measured samples")
            else:
                t, e, rms, peak = error
                self.err.set_data(*envelope(t, e))
                self.err.set_label(f"RMS {rms:.3g} m/s², peak {peak:.3g} m/s²")
            self.err_ax.legend(loc="upper right", fontsize=6.5)
            for k, line in enumerate(self.legs):
                line.set_data(*(([], []) if legs is None else envelope(legs[0], legs[1][:, k])))
            for limit, value in zip(self.limits, (None, None) if legs is None else legs[2:], strict=True):
                limit.set_visible(value is not None)
                if value is not None:
                    limit.set_ydata([value, value])
            for k, axis in enumerate(self.AXES):
                scale = 1e3 if k < 3 else 180.0 / math.pi
                for line, rows in zip(self.pose[axis], (pose, commanded), strict=True):
                    if rows.ndim == 2 and rows.shape[0] and rows.shape[1] == 7:
                        line.set_data(*envelope(rows[:, 0], rows[:, k + 1] * scale))
                    else:
                        line.set_data([], [])
            for ax in (self.err_ax, self.leg_ax, self.trans_ax, self.rot_ax):
                ax.relim(visible_only=True)
                ax.autoscale_view()
            return png(self.fig)


def run_figure(t_cmd: NDArray[np.float64], a_cmd: NDArray[np.float64], t_meas: NDArray[np.float64],
               a_meas: NDArray[np.float64], periods: NDArray[np.float64], psa_cmd: NDArray[np.float64] | None,
               psa_meas: NDArray[np.float64] | None, marks: Sequence[Mark] = ()) -> bytes:
    """One run's figure (`RunFigure`) drawn once."""
    return RunFigure(periods).render(t_cmd, a_cmd, t_meas, a_meas, psa_cmd, psa_meas, marks)


def thresholds_figure(aspects: Sequence[tuple[float, str]], max_angle_deg: float,
                      marks_deg: Sequence[float] = ()) -> bytes:
    """The paper's Fig. 2: Eq. 1's accelerations that start rocking [g] against the plate angle [deg], towards
    the low side (A_min+, solid: g·tan(α − β)) and the high side (A_min−, dashed: g·tan(α + β)), one colour per
    aspect ratio b/h given as (b/h, label); ``marks_deg`` angles drawn as vertical lines."""
    beta = np.radians(np.linspace(0.0, max_angle_deg, 200))
    with _figure(3.0) as (fig, axes):
        ax = axes[0, 0]
        for i, (aspect, label) in enumerate(aspects):
            alpha = math.atan(aspect)
            color = f"C{i % 10}"
            ax.plot(np.degrees(beta), np.tan(alpha - beta), color=color, label=rf"$A_{{\min +}}$ {label}")
            ax.plot(np.degrees(beta), np.tan(alpha + beta), color=color, ls="--", label=rf"$A_{{\min -}}$ {label}")
        for angle in marks_deg:
            ax.axvline(angle, color="0.5", lw=0.6, ls=":")
        ax.set_xlabel("plate inclination β [deg]")
        ax.set_ylabel(f"acceleration to start rocking [g] (g = {G:g} m/s²)")
        ax.set_xlim(0.0, max_angle_deg)
        ax.set_ylim(bottom=0.0)
        ax.legend(loc="upper left", ncols=2 if len(aspects) > 3 else 1)
        fig.subplots_adjust(left=0.09, right=0.99, bottom=0.14, top=0.97)
        return png(fig)


@dataclass(frozen=True)
class Curve:
    """A line or a set of points on a COR chart: angles [deg], rates [fraction], label and style."""

    angle_deg: NDArray[np.float64]
    cor: NDArray[np.float64]
    label: str
    style: str = "-"
    color: str | None = None


def _cor_axes(ax: Axes, curves: Sequence[Curve], title: str = "", legend: bool = True) -> None:
    for curve in curves:
        ax.plot(curve.angle_deg, 100.0 * np.asarray(curve.cor, dtype=float), curve.style, color=curve.color,
                label=curve.label, ms=3.5)
    ax.set_ylim(0.0, 102.0)
    ax.set_xlabel("β [deg]")
    ax.set_ylabel("COR [%]")
    if title:
        ax.set_title(title)
    if legend:
        ax.legend(loc="lower right")


def cor_figure(curves: Sequence[Curve], title: str = "") -> bytes:
    """One COR chart (the paper's Figs. 6, 7, 13): controlled-overturning rate [%] against the angle [deg]."""
    with _figure(3.0) as (fig, axes):
        _cor_axes(axes[0, 0], curves, title)
        fig.subplots_adjust(left=0.08, right=0.99, bottom=0.14, top=0.93 if title else 0.97)
        return png(fig)


def cor_grid_figure(panels: Sequence[tuple[str, Sequence[Curve]]], ncols: int = 3) -> bytes:
    """Small COR charts, one per body (the paper's Figs. 8–9): (title, curves) each; the legend on the first."""
    nrows = max(1, math.ceil(len(panels) / ncols))
    with _figure(1.9 * nrows + 0.3, ncols=ncols, nrows=nrows, sharex=True, sharey=True) as (fig, axes):
        for k, ax in enumerate(axes.ravel()):
            if k >= len(panels):
                ax.set_visible(False)
                continue
            title, curves = panels[k]
            _cor_axes(ax, curves, title, legend=k == 0)
            if k % ncols:
                ax.set_ylabel("")
        fig.subplots_adjust(left=0.07, right=0.99, bottom=0.35 / (1.9 * nrows + 0.3) + 0.06,
                            top=1 - 0.25 / (1.9 * nrows + 0.3), hspace=0.45, wspace=0.08)
        return png(fig)


def _handle(style: str, color: str | None) -> Line2D:
    """A legend entry drawn like a curve of format ``style`` (an optional marker o, ^ or s, then a line style)."""
    marker = style[0] if style[:1] in ("o", "^", "s") else None
    line = style[1:] if marker else style
    return Line2D([], [], color=color, marker=marker, ls=line or ("" if marker else "-"), ms=3.5)


def fig13_figure(average: Sequence[Curve], differences: Sequence[Curve], key: Sequence[Curve] = (),
                 limit_pp: float = 5.0) -> bytes:
    """The paper's Fig. 13 with a second panel: (a) the body-averaged COR [%] of the analysis (per model) and of
    the experiment against the angle [deg]; (b) analysis − experiment per body [percentage points], with the
    paper's ±``limit_pp`` band dashed. ``key``: the legend of (b) (label, style and colour; no data), drawn below
    the panels so that it never hides a point."""
    per_row = 5
    rows = math.ceil(len(key) / per_row)
    height = 2.8 + 0.16 * rows
    with _figure(height, ncols=2) as (fig, axes):
        left, right = axes[0]
        _cor_axes(left, average, "(a) average over the bodies")
        for curve in differences:
            right.plot(curve.angle_deg, 100.0 * np.asarray(curve.cor, dtype=float), curve.style, color=curve.color,
                       ms=3.5)
        for sign in (1, -1):
            right.axhline(sign * limit_pp, color="0.4", ls="--", lw=0.7)
        right.set_xlabel("β [deg]")
        right.set_ylabel("COR analysis − experiment [pp]")
        right.set_title("(b) difference per body")
        handles = [_handle(c.style, c.color) for c in key]
        if handles:
            fig.legend(handles, [c.label for c in key], loc="lower center", ncols=min(per_row, len(key)), frameon=False,
                       fontsize=6.5)
        bottom = (0.42 + 0.16 * rows) / height
        fig.subplots_adjust(left=0.08, right=0.99, bottom=bottom, top=1 - 0.22 / height, wspace=0.3)
        return png(fig)
