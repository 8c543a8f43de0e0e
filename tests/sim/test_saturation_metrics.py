"""Motor and rate saturation fractions, by hand."""

import numpy as np

from aerorelay.models.vehicle import hexarotor
from aerorelay.sim.metrics import saturation_metrics


def test_saturation_fractions_by_hand():
    veh = hexarotor(20.0)  # speeds in [16, 100] Hz, rates in [-300, 400] Hz/s
    speeds = np.full((4, 6), 60.0)
    rates = np.zeros((4, 6))
    speeds[0, 2] = 16.1  # within 1% of 16 Hz
    speeds[1, 0] = 99.5  # within 1% of 100 Hz
    speeds[2, 5] = 16.3  # 1.9% above the bound: not saturated
    rates[3, 1] = 398.0  # within 1% of 400 Hz/s
    rates[2, 4] = -290.0  # 3.3% from -300 Hz/s: not saturated
    m = saturation_metrics(speeds, rates, veh)
    assert m["motor_saturation_fraction"] == 0.5 and m["rate_saturation_fraction"] == 0.25
