"""The energy-aware cost term (shaft power) against the vehicle's own power model, and its effect."""

import casadi as ca
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from aerorelay.assembly import load_scenario
from aerorelay.assembly.parts import build, ocp_spec
from aerorelay.config.cost_terms import COST_TERMS
from aerorelay.control.terms import StageVars

SC = load_scenario("scenarios/nominal_tilted.toml")
SPEC = ocp_spec(SC)
TERM = {t.name: t for t in COST_TERMS}["shaft_power"]
XA = ca.SX.sym("xa", 12 + 6)
RESIDUAL = ca.Function("r", [XA], [TERM.residual(StageVars(SPEC, XA, None, {}))])


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(16.0, 100.0), min_size=6, max_size=6))
def test_shaft_power_residual_squared_is_the_vehicles_shaft_power(speeds):
    """|r|^2 = sum 2 pi c_tau Omega^3 (W), the power the metrics integrate into energy_kJ."""
    x = np.concatenate([np.zeros(12), speeds])
    r = np.asarray(RESIDUAL(x)).ravel()
    expected = sum(2 * np.pi * SC.platform.c_tau * s**3 for s in speeds)
    assert abs(r @ r - expected) <= 1e-9 * expected
    assert abs(r @ r - float(SPEC.vehicle.shaft_power(np.asarray(speeds)))) <= 1e-9 * expected


def test_shaft_power_weight_defaults_to_zero_and_is_a_weight_field():
    assert SC.controller.weights.shaft_power == 0.0 and TERM.terminal is None and not TERM.comms_aware


def test_a_shaft_power_weight_lowers_the_flights_energy():
    """8 s of the capacity-seeking relay at 1 m/s: weight 0.1 W^-1 uses less shaft energy than 0."""
    base = SC.with_updates({"controller.planner": "capacity", "sim.duration_s": 8.0})
    energy = {}
    for w in (0.0, 0.1):
        res = build(base.with_updates({"controller.weights.shaft_power": w})).closed_loop().run()
        speeds = np.column_stack([res.log[f"relay.Omega_{i}"] for i in range(1, 7)])
        energy[w] = float(np.sum(SPEC.vehicle.shaft_power(speeds)) * base.control_period_s)
    assert energy[0.1] < energy[0.0]
