"""Wind turbulence: the Dryden model (MIL-F-8785C, MIL-HDBK-1797), low-altitude form.

Below 1000 ft the scale lengths and intensities follow from the altitude ``h`` (ft inside the
formulas) and the wind speed at 20 ft (6 m), ``W20``:

- ``L_w = h``, ``L_u = L_v = h / (0.177 + 0.000823 h)^1.2``;
- ``sigma_w = 0.1 W20``, ``sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4``.

A vehicle moving at ``V`` relative to the air through a frozen turbulence field sees the one-sided
spectra (``omega`` rad/s, each integrating to ``sigma^2`` over ``[0, inf)``)

- ``Phi_u(omega) = (2 sigma_u^2 L_u / (pi V)) / (1 + (L_u omega / V)^2)``,
- ``Phi_v(omega) = (sigma_v^2 L_v / (pi V)) (1 + 3 (L_v omega / V)^2) / (1 + (L_v omega / V)^2)^2``, ``w`` alike,

whose autocorrelations are ``sigma_u^2 exp(-V tau / L_u)`` and ``sigma_v^2 (1 - V tau / (2 L_v))
exp(-V tau / L_v)``. The gusts come from white noise through the spectral square roots
``H_u(s) = sigma_u sqrt(2 L_u / (pi V)) / (1 + L_u s / V)`` and ``H_v(s) = sigma_v sqrt(L_v / (pi V))
(1 + sqrt(3) L_v s / V) / (1 + L_v s / V)^2`` (noise of two-sided intensity pi), discretized exactly
(the filters' states sampled with the covariance the continuous noise builds over a step, Van Loan's
method): the samples have the model's variances and correlations at any step.

``u`` lies along the mean wind (horizontal), ``v`` horizontal across it, ``w`` vertical; a relay
hovering in a mean wind of speed ``U`` meets the field at ``V = U`` (at least ``MIN_AIRSPEED_M_S``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm, solve_discrete_lyapunov

FT = 0.3048  # m per ft
LOW_ALTITUDE_MAX_M = 1000 * FT  # the low-altitude form holds below 1000 ft
MIN_ALTITUDE_M = 10 * FT  # L_w = h vanishes at the ground: the form is used from 10 ft up
MIN_AIRSPEED_M_S = 0.5  # a frozen field passes a vehicle at least this fast (the spectra divide by V)


@dataclass(frozen=True)
class DrydenParameters:
    """Intensities ``sigma`` (m/s) and scale lengths ``length`` (m) of the ``u, v, w`` components."""

    sigma: tuple[float, float, float]
    length: tuple[float, float, float]


def low_altitude_parameters(w20_m_s: float, altitude_m: float) -> DrydenParameters:
    """MIL-F-8785C low-altitude intensities and scale lengths from the wind speed at 6 m (20 ft,
    m/s) and the altitude (m, clamped to [10 ft, 1000 ft])."""
    if w20_m_s < 0:
        raise ValueError(f"wind speed at 6 m must be >= 0 m/s, got {w20_m_s}")
    h = min(max(altitude_m, MIN_ALTITUDE_M), LOW_ALTITUDE_MAX_M) / FT  # ft
    k = 0.177 + 0.000823 * h
    l_uv = h / k**1.2 * FT
    sigma_w = 0.1 * w20_m_s
    sigma_uv = sigma_w / k**0.4
    return DrydenParameters((sigma_uv, sigma_uv, sigma_w), (l_uv, l_uv, h * FT))


def _shaping_filter(sigma: float, length: float, airspeed: float, order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """State space ``(A, B, C)`` of ``H_u`` (order 1) or ``H_v`` / ``H_w`` (order 2) above."""
    T = length / airspeed
    if order == 1:
        g = sigma * math.sqrt(2.0 * length / (math.pi * airspeed))
        return np.array([[-1.0 / T]]), np.array([[1.0]]), np.array([[g / T]])
    g = sigma * math.sqrt(length / (math.pi * airspeed))
    # g (1 + sqrt(3) T s) / (1 + T s)^2 = (g sqrt(3) / T s + g / T^2) / (s^2 + 2 s / T + 1 / T^2), controllable form
    A = np.array([[0.0, 1.0], [-1.0 / T**2, -2.0 / T]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[g / T**2, g * math.sqrt(3.0) / T]])
    return A, B, C


def _discretized(A: np.ndarray, B: np.ndarray, dt: float, intensity: float) -> tuple[np.ndarray, np.ndarray]:
    """``(Ad, Qd)``: ``x_(k+1) = Ad x_k + n_k``, ``n_k ~ N(0, Qd)``, exact for white noise of two-sided
    intensity ``intensity`` (Van Loan)."""
    n = A.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n], M[:n, n:], M[n:, n:] = -A, intensity * B @ B.T, A.T
    E = expm(M * dt)
    Ad = E[n:, n:].T
    Qd = Ad @ E[:n, n:]
    return Ad, 0.5 * (Qd + Qd.T)


class DrydenTurbulence:
    """Gust velocities ``(u, v, w)`` (m/s, along the mean wind, across it, up) every ``dt`` s,
    seeded: ``sample()`` returns the next one. Starts from the stationary distribution."""

    def __init__(self, params: DrydenParameters, airspeed_m_s: float, dt: float, seed: int | np.random.SeedSequence = 0):
        if dt <= 0:
            raise ValueError(f"dt must be > 0 s, got {dt}")
        V = max(float(airspeed_m_s), MIN_AIRSPEED_M_S)
        self.rng = np.random.default_rng(seed)
        self.filters = []  # per component: Ad, the step noise's Cholesky factor, C, the state
        for i, order in enumerate((1, 2, 2)):
            A, B, C = _shaping_filter(params.sigma[i], params.length[i], V, order)
            Ad, Qd = _discretized(A, B, dt, math.pi)
            x = self.rng.multivariate_normal(np.zeros(len(A)), solve_discrete_lyapunov(Ad, Qd))  # stationary start
            self.filters.append([Ad, np.linalg.cholesky(Qd), C, x])

    def sample(self) -> np.ndarray:
        out = np.empty(3)
        for i, f in enumerate(self.filters):
            Ad, L, C, x = f
            out[i] = float((C @ x)[0])
            f[3] = Ad @ x + L @ self.rng.standard_normal(len(x))
        return out

    def record(self, n: int) -> np.ndarray:
        """The next ``n`` samples ``(n, 3)``."""
        return np.array([self.sample() for _ in range(n)])

