"""Issue 61, item 3: every planner's references are checked each step, built-in, registered by name or passed from
Python, one relay's or a network's: a relay left out or a non-finite reference holds the relay where it is, a
position outside the workspace is clipped, each counted in metrics.json and said once naming the planner by its
registered name; a planner that raises, or returns what is not a reference, is a named error. Before: a network
planner returning NaN or a reference 200 m outside the box flew 66-99% of the run on the brake law, unnamed and
"safe"; one that left a relay out was a raw KeyError."""

from __future__ import annotations

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.planning.base import PLANNERS, PlannerFailed, register_network_planner
from aerorelay.planning.fleet import held_reference

CHAIN = "scenarios/chain_two_relays.toml"


def _fly(name, make, duration_s=0.4):
    """Fly the chain with a network planner registered as ``name`` whose references for relay r2 are ``make(p)``."""

    @register_network_planner(name)
    def _factory(ctx):
        class Planner:
            def update(self, inp):
                refs = {n: held_reference(p) for n, p in ctx.starts.items()}
                out = make(ctx.starts["r2"])
                if out is None:
                    refs.pop("r2")
                else:
                    refs["r2"] = out
                return refs
        return Planner()

    try:
        sc = ar.load_scenario(CHAIN, set={"sim.duration_s": duration_s, "controller.planner": name})
        return sc, ar.simulate(sc)
    finally:
        PLANNERS.pop(name)


def _nan(p):
    ref = held_reference(p)
    ref.p_ref = np.full(3, np.nan)
    return ref


@pytest.mark.parametrize("make,said", [(_nan, "non-finite reference"), (lambda p: None, "left out of the planner's references")],
                         ids=["nan", "left-out"])
def test_a_relay_without_a_finite_reference_holds_where_it_is_counted_and_named(make, said, caplog):
    sc, r = _fly("test_bad_refs", make)
    m, df = r.metrics, r.timeseries
    assert m["reference_held_steps"] == m["steps"] and m["relays"]["r2"]["reference_held_steps"] == m["steps"]
    assert m["relays"]["r1"]["reference_held_steps"] == m["relays"]["r1"]["reference_clipped_steps"] == 0
    assert said in m["reference_first"]["r2"] and m["planner_name"] == "test_bad_refs"
    assert any("planner 'test_bad_refs': relay 'r2'" in rec.getMessage() for rec in caplog.records)
    start = np.array(sc.relay_list[1].start)
    assert np.abs(df[[f"r2.pd_{a}" for a in "xyz"]].to_numpy() - start).max() < 0.05  # held near where it is
    assert m["relays"]["r2"]["fallback_fraction"] == 0.0 and not m["unsafe"]


def test_a_reference_outside_the_workspace_is_clipped_and_counted():
    def far(p):
        ref = held_reference(p + np.array([0.0, 200.0, 0.0]))
        return ref
    sc, r = _fly("test_far_refs", far)
    m, df = r.metrics, r.timeseries
    assert m["reference_clipped_steps"] == m["steps"] and "outside the workspace" in m["reference_first"]["r2"]
    assert df["r2.pd_y"].max() <= sc.controller.workspace.max[1] + 1e-12


def test_a_planner_that_raises_or_returns_no_reference_is_named():
    def boom(p):
        raise ZeroDivisionError("my bug")
    with pytest.raises(PlannerFailed, match=r"planner 'test_boom' raised at t = 0\.000 s: ZeroDivisionError: my bug"):
        _fly("test_boom", boom)
    with pytest.raises(PlannerFailed, match=r"planner 'test_str' at t = 0\.000 s: relay 'r2': must be a Reference, got str"):
        _fly("test_str", lambda p: "up")
