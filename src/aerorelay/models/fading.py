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

    def __init__(self, k_db: float, seed: int | np.random.SeedSequence | None = None):
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


class ClarkeRicianFading:
    """Rician fading that evolves in time (Clarke / Jakes spectrum), one process per link.

    The diffuse part of each link is a sum of ``n_sinusoids`` unit phasors with random arrival
    angles ``alpha_m`` and phases: ``n(t) = M^-1/2 sum_m exp(j phi_m(t))``, ``phi_m`` advancing
    by ``2 pi f_D cos(alpha_m) dt`` per step, so ``E|n|^2 = 1`` and ``E[n(t) n*(t + tau)] =
    J0(2 pi f_D tau)`` (Clarke's autocorrelation) for a constant Doppler frequency ``f_D`` (Hz);
    ``f_D`` may change from step to step (the link's relative speed). ``h = sqrt(K/(K+1)) +
    sqrt(1/(K+1)) n``, amplitude ``|h|``, ``E|h|^2 = 1``. Seeded per run.
    """

    def __init__(self, k_db: float, n_links: int, seed: int | np.random.SeedSequence | None = None, n_sinusoids: int = 32):
        self.k = k_factor_linear(k_db)
        rng = np.random.default_rng(seed)
        self._cos = np.cos(rng.uniform(0.0, 2.0 * np.pi, (n_links, n_sinusoids)))
        self._phase = rng.uniform(0.0, 2.0 * np.pi, (n_links, n_sinusoids))
        self._m = n_sinusoids

    def diffuse(self) -> np.ndarray:
        """The diffuse part ``n`` per link now (complex, ``E|n|^2 = 1``)."""
        return np.exp(1j * self._phase).sum(axis=1) / math.sqrt(self._m)

    def advance(self, doppler_hz, dt: float) -> None:
        """Move every link ``dt`` (s) on at its Doppler frequency ``doppler_hz`` (Hz, per link)."""
        self._phase = self._phase + 2.0 * np.pi * np.asarray(doppler_hz, float)[:, None] * self._cos * dt

    def amplitude(self, doppler_hz, dt: float) -> np.ndarray:
        """The amplitudes ``|h|`` now, then advance every link by ``dt`` (s) at ``doppler_hz``."""
        if math.isinf(self.k):
            return np.ones(self._phase.shape[0])
        n = self.diffuse()
        self.advance(doppler_hz, dt)
        return np.abs(math.sqrt(self.k / (self.k + 1.0)) + math.sqrt(1.0 / (self.k + 1.0)) * n)
