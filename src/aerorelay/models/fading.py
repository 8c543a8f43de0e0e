"""Rician small-scale fading (robustness runs only; unknown to the controller, Sec. VIII-F).

Each link's complex gain is multiplied by ``h = sqrt(K/(K+1)) + sqrt(1/(K+1)) n`` with
``n ~ CN(0, 1)``, so ``E|h|^2 = 1``. The amplitude ``alpha = |h|`` scales the channel amplitude,
``alpha^2`` the received power. ``K = inf`` (dB) means no fading.
"""

from __future__ import annotations

import math

import numpy as np


def k_factor_linear(k_db: float) -> float:
    """Rician K-factor from dB to linear (``inf`` stays ``inf``)."""
    if k_db < 0 and not math.isinf(k_db):
        raise ValueError(f"K-factor must be >= 0 dB or inf, got {k_db}")
    return math.inf if math.isinf(k_db) else 10.0 ** (k_db / 10.0)


class RicianFading:
    """Seeded generator of Rician amplitudes with K-factor ``k_db`` (dB) and ``E[alpha^2] = 1``."""

    def __init__(self, k_db: float, seed: int | None = None):
        self.k_db = k_db
        self.k = k_factor_linear(k_db)
        self._rng = np.random.default_rng(seed)

    def amplitude(self, size=None) -> np.ndarray | float:
        """Draw independent amplitudes ``alpha = |h|`` (dimensionless)."""
        if math.isinf(self.k):
            return np.ones(size) if size is not None else 1.0
        los = math.sqrt(self.k / (self.k + 1.0))
        scatter = math.sqrt(1.0 / (self.k + 1.0))
        n = (self._rng.standard_normal(size) + 1j * self._rng.standard_normal(size)) / math.sqrt(2.0)
        return np.abs(los + scatter * n)

    def power_gain(self, size=None):
        """Draw independent power gains ``alpha^2`` (mean 1)."""
        return self.amplitude(size) ** 2
