"""The external-force observer (estimation/disturbance.py): against a constant unknown acceleration
its error shrinks by exp(-T / tau) per step (the formula), and without one it stays at zero."""

from __future__ import annotations

import math

import numpy as np

from aerorelay.estimation.disturbance import ExternalAccelerationObserver
from aerorelay.models.vehicle import hexarotor
from aerorelay.sim.closed_loop import plant_step_function

PERIOD, TAU = 0.02, 0.3


def _fly(a_true: np.ndarray, steps: int) -> list[np.ndarray]:
    veh = hexarotor(20.0)
    model = plant_step_function(veh, 500.0, PERIOD)
    obs = ExternalAccelerationObserver(model, PERIOD, TAU)
    x, u = veh.hover_state(), np.zeros(veh.n_rotors)
    out = []
    for _ in range(steps):
        x_next = np.asarray(model(x, u, np.r_[a_true, 0.0, 0.0, 0.0])).ravel()
        out.append(obs.update(x, u, x_next).copy())
        x = x_next
    return out


def test_constant_disturbance_error_decays_at_the_stated_rate():
    a = np.array([0.8, -0.3, 0.2])
    est = _fly(a, 60)
    for k in (1, 10, 30, 60):
        expected = math.exp(-k * PERIOD / TAU) * np.linalg.norm(a)
        assert abs(np.linalg.norm(est[k - 1] - a) - expected) < 1e-6 * np.linalg.norm(a) + 1e-9


def test_no_disturbance_no_estimate():
    est = _fly(np.zeros(3), 20)
    assert np.max(np.abs(est[-1])) < 1e-9
