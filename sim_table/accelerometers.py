"""The plate's motion differentiated: pose rates for the specimens, specific force for virtual accelerometers.

:class:`PlateTrack` keeps the last two achieved (true) poses of the 1 kHz tick and returns, for each new tick,
the **previous** tick's pose with central-difference rates ``(p[k+1] − p[k−1]) / 2dt``: one tick late, smooth and
consistent with the pose (what ``sim_table.specimens`` asks for).

:class:`Accelerometers` are points fixed on the plate (``places`` (m, 3) [m], plate frame: x along the fall line,
+x downhill, z normal to the plate, up), each mounted with its own axes (``mountings`` (m, 3, 3): the matrix ``A``
of its calibration sheet, ``analysis.table.sensors.SensorSheet.mounting``; default the plate's axes). Each
measures, at the same one-tick-late instants, the specific force in its own axes ``s = A f``, ``f = Rᵀ (a − g)``
the plate frame's, with ``g = (0, 0, −9.81) m/s²`` in the base frame and ``a`` the central second difference of
the point's position ``x = t + R r`` [m/s²] (for a rigid plate ``a = a_O + α × r + ω × (ω × r)``), plus Gaussian
noise of σ ``noise`` (seeded; a sensor's own σ in :attr:`Accelerometers.sigma`, raised by a fault): at rest on a
plate tilted by pitch β, ``f = (−g sin β, 0, g cos β)``.
"""

from __future__ import annotations

import numpy as np

from analysis.body import G
from analysis.table.model import rotation_matrices
from analysis.table.sensors import SensorSheets

GRAVITY = np.array([0.0, 0.0, -G])
"""Gravity in the base frame [m/s²]."""


class PlateTrack:
    """The last two achieved poses; :meth:`advance` returns the plate state one tick late (module docstring)."""

    def __init__(self, dt: float, pose: np.ndarray | None = None) -> None:
        self.dt = float(dt)
        start = np.zeros(6) if pose is None else np.asarray(pose, dtype=float)
        self._history = np.stack([start, start])

    def advance(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """New ticks' poses (k, 6) → the k poses one tick earlier (k, 6), their rates (k, 6) [m/s, rad/s] and the
        window (k + 2, 6) the differences used (for :meth:`Accelerometers.measure`)."""
        window = np.concatenate([self._history, poses])
        self._history = window[-2:].copy()
        return window[1:-1], (window[2:] - window[:-2]) / (2.0 * self.dt), window


class Accelerometers:
    """Virtual accelerometers at ``places`` (m, 3) [m, plate frame] with their axes ``mountings`` (m, 3, 3) (plate
    frame → the sensor's axes; None: the plate's), noise σ ``noise`` [m/s²] from ``seed``."""

    def __init__(self, places: np.ndarray, dt: float, *, mountings: np.ndarray | None = None, noise: float = 0.02,
                 seed: int = 0) -> None:
        self.places = np.atleast_2d(np.asarray(places, dtype=float))
        if self.places.shape[1] != 3 or not np.isfinite(self.places).all():
            raise ValueError(f"accelerometer places must be finite (m, 3) rows, got {self.places.shape}")
        count = len(self.places)
        self.mountings = np.broadcast_to(np.eye(3), (count, 3, 3)) if mountings is None else np.asarray(mountings,
                                                                                                          dtype=float)
        if self.mountings.shape != (count, 3, 3):
            raise ValueError(f"accelerometer mountings must be one 3×3 matrix a place, got {self.mountings.shape} for "
                             f"{count} places")
        if not noise >= 0:
            raise ValueError(f"accelerometer noise must be >= 0 m/s², got {noise!r}")
        self.dt = float(dt)
        self.noise = float(noise)
        self.sigma = np.full(len(self.places), self.noise)
        """Each sensor's noise σ now [m/s²] (the emulator raises one for ``--accel-noisy``)."""
        self._rng = np.random.default_rng(seed)

    def measure(self, window: np.ndarray) -> np.ndarray:
        """Specific force (k, m, 3) [m/s², each sensor's axes] at the k inner poses of ``window`` (k + 2, 6)."""
        R = rotation_matrices(window)  # (k + 2, 3, 3)
        points = window[:, None, :3] + np.einsum("kij,mj->kmi", R, self.places)  # (k + 2, m, 3)
        a = (points[2:] - 2.0 * points[1:-1] + points[:-2]) / (self.dt * self.dt)
        force = np.einsum("mij,kmj->kmi", self.mountings, np.einsum("kji,kmj->kmi", R[1:-1], a - GRAVITY))
        if self.sigma.any():
            force += self._rng.normal(0.0, 1.0, force.shape) * self.sigma[None, :, None]
        return force


def sheet_accelerometers(sheets: SensorSheets) -> tuple[np.ndarray, np.ndarray]:
    """The places (m, 3) [m, plate frame] and mountings (m, 3, 3) of accelerometers 0 … the largest id with a
    calibration sheet in ``sheets``: each at its sheet's place with its sheet's axes, one without a sheet at the
    plate's centre with the plate's axes; no sheet: one accelerometer, at the centre."""
    count = 1 + max((int(name) for name in sheets.sheets), default=0)
    places, mountings = np.zeros((count, 3)), np.tile(np.eye(3), (count, 1, 1))
    for name, sheet in sheets.sheets.items():
        places[int(name)] = sheet.place_m
        mountings[int(name)] = sheet.mounting()
    return places, mountings
