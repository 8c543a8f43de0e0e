"""What a receiver measures of the jammers: its interference-plus-noise power through an energy detector.

An energy detector averages ``|x_i|^2`` over ``n`` complex baseband samples of a signal of mean
power ``P`` (W). For Gaussian samples the average is ``P X`` with ``X = chi^2_(2n) / (2n)``, i.e.
``X ~ Gamma(shape = n, scale = 1/n)``: mean 1, variance ``1/n``. In dB (``10 log10``) the
measurement has mean ``10 log10 P + kappa (psi(n) - ln n)`` and variance ``kappa^2 psi'(n)``
(``kappa = 10 / ln 10``, ``psi`` the digamma function): the estimator models both. A detector
``bias_db`` (calibration error) scales every measurement and is not known to the estimator.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import digamma, polygamma

KAPPA_DB = 10.0 / math.log(10.0)  # dB per neper of power


def detector_log_mean_db(n_samples: int) -> float:
    """``E[10 log10 X]`` for ``X = chi^2_(2n)/(2n)``, dB (``kappa (psi(n) - ln n)``, about ``-kappa / 2n``)."""
    return float(KAPPA_DB * (digamma(n_samples) - math.log(n_samples)))


def detector_log_std_db(n_samples: int) -> float:
    """Standard deviation of ``10 log10 X``, dB (``kappa sqrt(psi'(n))``, about ``kappa / sqrt(n)``)."""
    return float(KAPPA_DB * math.sqrt(polygamma(1, n_samples)))


class EnergyDetector:
    """Seeded energy detector over ``n_samples`` complex samples with a ``bias_db`` calibration error."""

    def __init__(self, n_samples: int, bias_db: float = 0.0, seed: int | np.random.SeedSequence | None = None):
        if n_samples < 1:
            raise ValueError(f"n_samples must be >= 1, got {n_samples}")
        self.n = int(n_samples)
        self.scale = 10.0 ** (bias_db / 10.0)
        self._rng = np.random.default_rng(seed)

    def measure(self, power_w):
        """The detector's reading (W) of received powers ``power_w`` (W, scalar or array)."""
        p = np.asarray(power_w, float)
        return p * self.scale * self._rng.gamma(self.n, 1.0 / self.n, size=p.shape)
