"""The relay's state by name (models.state): one layout, one pack/unpack, the log's names."""

from __future__ import annotations

import numpy as np

from aerorelay.models.state import ETA, OMEGA, RIGID_NAMES, ROTORS, P, V, pack, unpack
from aerorelay.models.vehicle import hexarotor
from aerorelay.sim.log_schema import VEHICLE_STATE


def test_pack_and_unpack_are_inverse_and_the_layout_is_the_papers():
    """x = [p, eta, v, omega, Omega] (paper eq. 1): 3 + 3 + 3 + 3 + n, in that order; the log names x[RIGID] as it."""
    n = 6
    x = np.arange(12 + n, dtype=float)
    p, eta, v, w, om = unpack(x)
    assert [list(a) for a in (p, eta, v, w)] == [[0, 1, 2], [3, 4, 5], [6, 7, 8], [9, 10, 11]] and list(om) == list(range(12, 18))
    assert np.array_equal(pack(p, eta, v, w, om), x)
    assert VEHICLE_STATE == RIGID_NAMES and RIGID_NAMES[P.start] == "p_x" and RIGID_NAMES[ETA.start] == "phi"
    assert RIGID_NAMES[V.start] == "v_x" and RIGID_NAMES[OMEGA.start] == "omega_x"


def test_the_hover_state_is_packed_at_the_named_places():
    veh = hexarotor(20.0)
    x = veh.hover_state((1.0, 2.0, 3.0))
    assert np.array_equal(x[P], [1.0, 2.0, 3.0]) and not np.any(x[ETA]) and not np.any(x[V]) and not np.any(x[OMEGA])
    assert np.array_equal(x[ROTORS], veh.hover_speeds())
