"""The noise-floor suspender: each plate accelerometer whose sheet gives a noise floor (``[sensors.ID]
noise_floor_m_s2``, ``analysis.table.sensors``) is measured at rest before every run, and the sequence waits while
one is noisier than its sheet says (``docs/limits.md``, Suspenders).

The measure is each axis's RMS about its mean [m/s²] over the latest :data:`WINDOW_S` s (controller time) of the
sensor's samples, taken while the table holds still (armed, before the run's drive): at rest a reading is gravity
and the sensor's noise, so the mean is gravity's share and the rest is the noise. A sensor is noisy when any axis's
RMS is above its floor; a sensor that sends no full window within :data:`WAIT_S` s is not judged.
"""

from __future__ import annotations

import time
from collections import deque

import numpy as np

from analysis.table.sensors import SensorSheet, SensorSheets
from drivers.controller import AccelBatch, Subscription, TableController

WINDOW_S = 0.5
"""The span of samples an axis's RMS is taken over [s, controller time]."""

WAIT_S = 5.0
"""Longest wait for a first full window of every watched sensor [s, host time]."""

_AXES = ("x", "y", "z")


def axis_rms(samples: np.ndarray) -> np.ndarray:
    """Each axis's RMS about its mean (3,) [m/s²] of ``samples`` (n, 3) [m/s², plate frame]."""
    values = np.asarray(samples, dtype=float)
    return np.sqrt(np.mean((values - values.mean(axis=0)) ** 2, axis=0))


def noisy(sheet: SensorSheet, samples: np.ndarray) -> str | None:
    """Why the sensor of ``sheet`` is noisy over ``samples`` (n, 3) [m/s²] taken at rest, or None when every axis's
    RMS is at or below its noise floor (or the sheet gives none)."""
    floor = sheet.noise_floor_m_s2
    if floor is None:
        return None
    rms = axis_rms(samples)
    worst = int(np.argmax(rms))
    if rms[worst] <= floor:
        return None
    return (f"accelerometer {sheet.sensor} is noisy at rest: {_AXES[worst]} reads {rms[worst]:.3g} m/s² RMS, above "
            f"its sheet's noise floor {floor:g} m/s²")


class NoiseWatch:
    """The latest :data:`WINDOW_S` s of samples of every sensor with a noise floor in ``sheets``, from ``table``'s
    accelerometer batches received after it was opened (a context manager: it subscribes on entry, unsubscribes on
    exit; with no sensor to watch it does neither)."""

    def __init__(self, table: TableController, sheets: SensorSheets) -> None:
        self.table = table
        self.sheets = {int(name): sheet for name, sheet in sheets.sheets.items()
                       if sheet.noise_floor_m_s2 is not None}
        self._windows: dict[int, deque[AccelBatch]] = {sensor: deque() for sensor in self.sheets}
        self._subscription: Subscription[AccelBatch] | None = None
        self.silent: list[int] = []
        """The watched sensors without a full window after the first wait (not judged)."""

    def __enter__(self) -> NoiseWatch:
        if self.sheets:
            self._subscription = self.table.accelerations()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._subscription is not None:
            self._subscription.close()
            self._subscription = None

    def reasons(self) -> list[str]:
        """Why the sequence must wait for the sensors' noise (empty: it need not). The first call waits until every
        watched sensor has a full window (at most :data:`WAIT_S` s); later calls take the samples that came since
        and judge the latest window."""
        if self._subscription is None:
            return []
        self._take(self._subscription.drain())
        deadline = time.monotonic() + WAIT_S
        while not all(self._full(sensor) for sensor in self.sheets) and time.monotonic() < deadline:
            try:
                self._take([self._subscription.get(timeout=max(deadline - time.monotonic(), 0.0))])
            except TimeoutError:
                break
        self.silent = [sensor for sensor in self.sheets if not self._full(sensor)]
        found = []
        for sensor, sheet in self.sheets.items():
            if self._full(sensor):
                why = noisy(sheet, self._latest(sensor))
                if why is not None:
                    found.append(why)
        return found

    def _take(self, batches: list[AccelBatch]) -> None:
        for batch in batches:
            window = self._windows.get(batch.sensor_id)
            if window is None or not len(batch.samples):
                continue
            window.append(batch)
            end = int(batch.times_ns()[-1])
            while len(window) > 1 and int(window[1].t_start_ns) <= end - WINDOW_S * 1e9:
                window.popleft()  # the next batch still starts a full window before the newest sample

    def _latest(self, sensor: int) -> np.ndarray:
        """The samples (n, 3) [m/s²] of the latest :data:`WINDOW_S` s of ``sensor``."""
        window = self._windows[sensor]
        times = np.concatenate([batch.times_ns() for batch in window])
        samples = np.concatenate([batch.samples for batch in window])
        return samples[times > times[-1] - WINDOW_S * 1e9]

    def _full(self, sensor: int) -> bool:
        """Whether ``sensor``'s samples span :data:`WINDOW_S` s (each sample standing for its spacing)."""
        window = self._windows[sensor]
        if not window:
            return False
        last = window[-1]
        return int(last.times_ns()[-1]) + last.spacing_ns - int(window[0].t_start_ns) >= WINDOW_S * 1e9 * 0.999

