"""Planners named from TOML (issue 46): ``controller.planner`` takes any registered planner (the
built-ins and one registered before the scenario is loaded), an unknown name is a named error listing
them, and the paper's generator has one name for one relay and fleets ("paper" is read as it)."""

from __future__ import annotations

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.config import ScenarioError
from aerorelay.planning.base import PLANNERS, register_planner

NOMINAL = "scenarios/nominal_tilted.toml"


class _Hover:
    """Holds the relay where it starts."""

    def __init__(self):
        self.p = None

    def update(self, inp):
        if self.p is None:
            self.p = inp.p1.copy()
        return ar.Reference(p_opt=self.p.copy(), p_ref=self.p.copy(), v_ref=np.zeros(3), a_ref=np.zeros(3))


def test_a_registered_planner_is_named_in_the_scenario_and_flies():
    if "hover_test" not in PLANNERS:
        register_planner("hover_test")(lambda ctx: _Hover())
    sc = ar.load_scenario(NOMINAL, set={"controller.planner": "hover_test", "controller.variant": "unconstrained",
                                        "sim.duration_s": 0.5})
    r = ar.simulate(sc)
    assert not r.metrics["unsafe"]
    start = np.array(sc.nodes.relay)
    assert np.allclose(r.timeseries[["relay.pd_x", "relay.pd_y", "relay.pd_z"]].to_numpy(), start)  # its reference, flown


def test_an_unknown_planner_is_named_with_the_registered_ones():
    with pytest.raises(ScenarioError, match=r"controller\.planner: no planner registered as 'nope'; registered: .*capacity.*trajectory_generator"):
        ar.load_scenario(NOMINAL, set={"controller.planner": "nope"})
    with pytest.raises(ScenarioError, match=r"controller\.planner"):
        ar.load_scenario(NOMINAL, set={"controller.planner": "Bad Name"})


def test_the_papers_generator_has_one_name():
    assert ar.load_scenario(NOMINAL, set={"controller.planner": "paper"}).controller.planner == "trajectory_generator"
    chain = ar.load_scenario("scenarios/chain_two_relays.toml", set={"controller.planner": "paper"})
    assert chain.planner == "trajectory_generator" and "paper" not in chain.to_toml().split("[controller]")[1].split("\n[")[0]
