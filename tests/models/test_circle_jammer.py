"""A circling jammer (issue 48: ``[jammer] path = "circle"``, one table instead of every lap's
polygon): its position, velocity and acceleration from the circle's formula, the direction of turn,
its start due east of the center, and the named errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.config import ScenarioError

NOMINAL = "scenarios/nominal_tilted.toml"
CIRCLE = {"jammer.path": "circle", "jammer.center_m": [0.0, -20.0, 1.72], "jammer.radius_m": 5.0, "jammer.period_s": 20.0}


@pytest.mark.parametrize("clockwise", [False, True])
def test_the_jammer_circles_by_the_formula(clockwise):
    sc = ar.load_scenario(NOMINAL, set={**CIRCLE, "jammer.clockwise": clockwise}, unset=["jammer.position"])
    jam = ar.build_scene(sc).jammers[0]
    assert sc.jammer.position == [5.0, -20.0, 1.72]  # its start: due east of the center
    s = -1.0 if clockwise else 1.0
    for t in (0.0, 3.0, 7.5, 21.0, 100.0):
        th = s * 2 * math.pi * t / 20.0
        np.testing.assert_allclose(jam.position_at(t), [5 * math.cos(th), -20 + 5 * math.sin(th), 1.72], atol=1e-12)
    st = jam.path.state(5.0)  # a quarter lap: north of the center (counter-clockwise) or south
    np.testing.assert_allclose(st.p, [0.0, -20 + s * 5.0, 1.72], atol=1e-12)
    w = 2 * math.pi / 20.0
    np.testing.assert_allclose(np.linalg.norm(st.v), 5 * w, rtol=1e-12)
    np.testing.assert_allclose(st.a, -(w**2) * (st.p - [0.0, -20.0, 1.72]), atol=1e-12)  # centripetal
    r = ar.simulate(sc.with_updates({"sim.duration_s": 0.3}))
    assert not r.metrics["unsafe"] and r.timeseries["jam_jammer_x"].iloc[0] == pytest.approx(5.0)


@pytest.mark.parametrize("sets,named", [
    ({"jammer.path": "circle", "jammer.center_m": [0.0, -20.0, 1.72]}, "needs radius_m, period_s"),
    ({"jammer.radius_m": 5.0}, r"radius_m apply to path = \"circle\" only"),
    ({**CIRCLE, "jammer.position": [0.0, 0.0, 1.72]}, "is not the circle's start"),
])
def test_an_incomplete_or_contradicting_circle_is_named(sets, named):
    with pytest.raises(ScenarioError, match=named):
        ar.load_scenario(NOMINAL, set=sets, unset=[] if "jammer.position" in sets else ["jammer.position"])
