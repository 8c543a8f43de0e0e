"""The air (sim/air.py): the wind series (mean alone constant; gusts seeded, along and across the
mean wind), the plant with drag equal to the plant without in still air at rest, and the drag
accelerating a hovering relay downwind as the formula says."""

from __future__ import annotations

import numpy as np

from aerorelay.models.drag import drag_coefficients
from aerorelay.models.vehicle import hexarotor
from aerorelay.sim.air import WindSeries, WindSettings
from aerorelay.sim.closed_loop import plant_step_function


def test_mean_wind_alone_is_constant():
    s = WindSeries(WindSettings(mean=(3.0, -1.0, 0.0)), 0.01, seed=1)
    assert all(np.array_equal(s.next(), [3.0, -1.0, 0.0]) for _ in range(5))


def test_gusts_are_seeded_and_turn_with_the_mean_wind():
    along_y = WindSettings(mean=(0.0, 8.0, 0.0), gusts=True, w20_m_s=8.0, altitude_m=20.0)
    s3, t3, s4 = WindSeries(along_y, 0.05, seed=3), WindSeries(along_y, 0.05, seed=3), WindSeries(along_y, 0.05, seed=4)
    a = np.array([s3.next() for _ in range(200)])
    b = np.array([t3.next() for _ in range(200)])
    c = np.array([s4.next() for _ in range(200)])
    assert np.array_equal(a, b) and not np.allclose(a, c)  # one seed, one series; another seed, another
    s = WindSeries(along_y, 0.05, seed=4)
    rec = np.array([s.next() for _ in range(40_000)]) - [0.0, 8.0, 0.0]
    # u (along the mean wind, here world y) and v (across, world -x) share the low-altitude sigma_u = sigma_v
    sigma_w = 0.1 * 8.0
    h = 20.0 / 0.3048
    sigma_uv = sigma_w / (0.177 + 0.000823 * h) ** 0.4
    assert abs(rec[:, 1].std() / sigma_uv - 1) < 0.15
    assert abs(rec[:, 0].std() / sigma_uv - 1) < 0.15
    assert abs(rec[:, 2].std() / sigma_w - 1) < 0.15


def test_plant_with_drag_matches_plant_without_in_still_air_at_rest():
    veh = hexarotor(20.0)
    drag = drag_coefficients([0.05, 0.05, 0.12], 1.225)
    plain, windy = plant_step_function(veh, 1000.0, 0.01), plant_step_function(veh, 1000.0, 0.01, drag=drag)
    x, u, d = veh.hover_state([1.0, 2.0, 3.0]), np.zeros(veh.n_rotors), np.zeros(6)
    assert np.allclose(np.asarray(windy(x, u, d, np.zeros(3))), np.asarray(plain(x, u, d)), rtol=0, atol=1e-12)


def test_hovering_relay_accelerates_downwind_by_the_drag():
    veh = hexarotor(20.0)
    drag = drag_coefficients([0.05, 0.05, 0.12], 1.225)
    windy = plant_step_function(veh, 1000.0, 0.01, drag=drag)
    x = np.asarray(windy(veh.hover_state(), np.zeros(veh.n_rotors), np.zeros(6), [6.0, 0.0, 0.0])).ravel()
    expected = drag[0] * 36.0 / veh.mass * 0.01  # m/s after 10 ms (the relative speed barely changes)
    assert abs(x[6] - expected) < 0.01 * expected
