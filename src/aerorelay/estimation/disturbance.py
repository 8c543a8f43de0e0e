"""An external-force observer: what the relay's model does not explain of its measured velocity
(wind drag, gusts, a payload), as an acceleration the NMPC's model adds (offset-free tracking).

Each control step the relay predicts its velocity over the step flown with its own model and the
current estimate ``a_hat`` (m/s^2, world), then moves the estimate toward the unexplained part:
``a_hat <- a_hat + (1 - exp(-T / tau)) (v_measured - v_predicted) / T``, with ``T`` the control period and
``tau`` the observer's time constant. For a constant disturbance ``a`` the error shrinks by
``exp(-T / tau)`` per step (a first-order lag of ``tau`` seconds): the estimate converges to ``a``.
It sees only the relay's state and its own inputs, never the wind.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from ..models.state import V


class ExternalAccelerationObserver:
    """``update(x_before, u, x_now)`` after each control step; ``estimate`` is ``a_hat`` (m/s^2, world).

    ``model_step(x, u, d) -> x``: the relay's model over one control period with ``d = (a, alpha)``
    held (``sim.closed_loop.plant_step_function`` without drag)."""

    def __init__(self, model_step: ca.Function, period_s: float, time_constant_s: float):
        if period_s <= 0 or time_constant_s <= 0:
            raise ValueError(f"observer: period ({period_s} s) and time constant ({time_constant_s} s) must be > 0")
        self.model_step, self.period = model_step, period_s
        self.gain = 1.0 - math.exp(-period_s / time_constant_s)
        self.estimate = np.zeros(3)

    def update(self, x_before: np.ndarray, u: np.ndarray, x_now: np.ndarray) -> np.ndarray:
        """The new estimate from the step flown from ``x_before`` with ``u`` to ``x_now``."""
        d = np.concatenate([self.estimate, np.zeros(3)])
        v_pred = np.asarray(self.model_step(x_before, u, d)).ravel()[V]
        innovation = (np.asarray(x_now, float)[V] - v_pred) / self.period
        if np.all(np.isfinite(innovation)):
            self.estimate = self.estimate + self.gain * innovation
        return self.estimate
