"""The jammer estimator's measurements: readings being averaged into one measurement, the
time-ordered window of measurements Gauss-Newton fits, and the grid filter's cells."""

from __future__ import annotations

import math

import numpy as np

from ..models.sensing import KAPPA_DB


class PendingReadings:
    """Readings of one receiver being averaged: count, sums of power (W), position and axis."""

    def __init__(self):
        self.count, self.power = 0, 0.0
        self.position, self.axis = np.zeros(3), np.zeros(3)

    def add(self, position, axis, reading_w: float) -> None:
        self.position = self.position + np.asarray(position, float)
        self.axis = self.axis + np.asarray(axis, float)
        self.power += reading_w
        self.count += 1


class MeasurementWindow:
    """Time-ordered measurements: time (s), receiver, position and axis (world), reading (dB)."""

    def __init__(self, capacity: int, n_cells: int = 0):
        c = 2 * capacity
        self.capacity = capacity
        # per row, the gain from every grid cell to its pose (kept for the pair search: computed once,
        # when the measurement came in; n_cells = 0 keeps none)
        self.cell_gains = np.zeros((c, n_cells))
        self.t, self.z = np.zeros(c), np.zeros(c)
        self.rx, self.ax, self.ri = np.zeros((c, 3)), np.zeros((c, 3)), np.zeros(c, dtype=np.intp)
        self.jitter2 = np.zeros(c)  # rad^2: mean squared angle of the averaged axes about their mean
        self.appended = 0  # rows appended since the start
        self.lo = self.hi = 0

    def append(self, t: float, ri: int, rx, ax, y: float, jitter2: float = 0.0, cell_gains=None) -> None:
        if self.hi == self.t.size:  # compact: move the live rows to the front
            n = self.hi - self.lo
            for a in (self.t, self.z, self.rx, self.ax, self.ri, self.jitter2, self.cell_gains):
                a[:n] = a[self.lo:self.hi]
            self.lo, self.hi = 0, n
        k = self.hi
        self.t[k], self.ri[k], self.rx[k], self.ax[k], self.jitter2[k] = t, ri, rx, ax, jitter2
        self.z[k] = KAPPA_DB * math.log(y)
        if self.cell_gains.shape[1]:
            if cell_gains is None or np.shape(cell_gains) != (self.cell_gains.shape[1],):
                raise ValueError(f"window: a row needs its {self.cell_gains.shape[1]} cell gains, got "
                                 f"{None if cell_gains is None else np.shape(cell_gains)}")
            self.cell_gains[k] = cell_gains
        self.hi += 1
        self.appended += 1
        if self.hi - self.lo > self.capacity:
            self.lo = self.hi - self.capacity

    def rows(self, most: int) -> np.ndarray:
        """Indices of at most ``most`` rows: all when fewer, else evenly thinned (the newest kept)."""
        n = self.hi - self.lo
        if n <= most:
            return np.arange(self.lo, self.hi)
        return np.unique(np.linspace(self.hi - 1, self.lo, most).round().astype(np.intp))

    def __len__(self) -> int:
        return self.hi - self.lo


def cell_grid(lo: np.ndarray, hi: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Cell centres ``(C, 3)`` of a regular grid of cells about ``spacing`` (m) over the box, and the cells' sides."""
    axes, sides = [], []
    for a, b in zip(lo, hi, strict=True):
        n = max(1, round((b - a) / spacing))
        axes.append(a + (np.arange(n) + 0.5) * (b - a) / n)
        sides.append((b - a) / n)
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3), np.array(sides)
