"""The OCP as data: named stage parameters, any number of constraints, dimension checks."""

import casadi as ca
import numpy as np
import pytest

from aerorelay.assembly import parse_scenario
from aerorelay.assembly.parts import ocp_spec, weight_parameters
from aerorelay.control.linearization import check_dimensions, stage_linearization, terminal_linearization
from aerorelay.control.nmpc import NMPC, NmpcSettings
from aerorelay.control.ocp import OcpSpec
from aerorelay.control.params import StageParams
from aerorelay.control.terms import CONSTRAINTS, Constraint

SC = parse_scenario({})


def test_stage_params_symbol_and_matrix_share_one_layout():
    sp = StageParams([("a", 3), ("b", 1), ("c", 2)])
    P = sp.matrix(4, {"a": [1.0, 2.0, 3.0], "b": np.arange(4.0), "c": np.ones((2, 4))})
    sym = sp.symbol()
    f = ca.Function("f", [sym], [sp.unpack(sym)["b"] * 10 + sp.unpack(sym)["a"][2]])
    assert float(f(P[:, 2])) == pytest.approx(2 * 10 + 3.0)
    np.testing.assert_array_equal(P[sp["a"], 3], [1.0, 2.0, 3.0])


@pytest.mark.parametrize("values,match", [
    ({"a": [1.0, 2.0, 3.0], "b": 0.0}, "without a value: c"),
    ({"a": [1.0, 2.0], "b": 0.0, "c": 0.0}, "'a': expected"),
    ({"a": 0.0, "b": 0.0, "c": 0.0, "d": 1.0}, "unknown stage parameter 'd'"),
])
def test_stage_params_reject_bad_values_by_name(values, match):
    sp = StageParams([("a", 3), ("b", 1), ("c", 2)])
    with pytest.raises(ValueError, match=match):
        sp.matrix(4, values)


def test_dimensions_follow_the_vehicle_and_the_constraint_list():
    quad = parse_scenario({"platform": {"rotor_count": 4, "tilt_deg": 0.0}})
    spec = ocp_spec(quad)
    assert (spec.nx, spec.nw, spec.ng, spec.ns) == (12 + 8, 4 + 1, 1, 1)
    unc = ocp_spec(SC.with_updates({"controller.variant": "unconstrained"}))
    assert (unc.nw, unc.ng, unc.ns) == (6, 0, 0) and "sw_misalignment" not in unc.params


def test_dimension_check_names_the_block_that_does_not_fit():
    spec = ocp_spec(SC)
    other = ocp_spec(SC.with_updates({"controller.variant": "unconstrained"}))
    with pytest.raises(ValueError, match="stage_lin input w"):
        check_dimensions(spec, stage_linearization(other), terminal_linearization(spec))


def _two_constraint_spec():
    # a second, hard constraint: z >= 1 m (one row)
    floor = Constraint("altitude_floor", lambda s: s.pos[2] - 1.0, "z >= 1 m", soft=False, comms_aware=False)
    # a second soft one with two rows: |x|, |y| <= 6 m as 6 - x >= 0 and 6 + x >= 0
    box = Constraint("x_band", lambda s: ca.vertcat(6.0 - s.pos[0], 6.0 + s.pos[0]), "|x| <= 6 m")
    base = ocp_spec(SC)
    return OcpSpec(**{**base.__dict__, "constraints_all": (*CONSTRAINTS, floor, box)})


def test_engine_and_conic_route_agree_with_several_constraints():
    """Three constraints, four rows, two slacks: both QP routes build and take the same step."""
    spec = _two_constraint_spec()
    assert (spec.ng, spec.ns, spec.nw) == (4, 2, 8)
    home = np.array([0.0, 0.0, 5.0])
    x = spec.vehicle.hover_state(home)
    x[3:6] = np.radians([4.0, -3.0, 10.0])
    tk = spec.ts * np.arange(spec.horizon + 1)
    P = spec.params.matrix(spec.horizon + 1, {
        "p_ref": np.array([7.0, 0.3, 0.5])[:, None] + 0 * tk, "v_ref": 0.0, "rho_d": [0, 0, 1.0], "psi_ref": 0.0, "p2": [3.0, 1.0, 8.0],
        "mu": 0.5, **weight_parameters(SC, spec), "sw_slack_x_band": 100.0})  # reference beyond x = 6 and below z = 1
    infos, plans = [], []
    for backend in ("casadi", "hpipm"):
        ctrl = NMPC(spec, NmpcSettings(backend=backend, tol_comp=1e-7, iter_max=200))
        ctrl.reset(np.concatenate([x, np.zeros(6)]))
        for _ in range(15):
            info = ctrl.step(x, np.zeros(6), P, shift=False)
            assert info.ok, (backend, info.status)
        infos.append(info)
        plans.append(ctrl.guess())
    np.testing.assert_allclose(infos[0].u, infos[1].u, rtol=1e-3, atol=0.5)
    from aerorelay.control.ocp import unpack_plan

    (Xa, Wa), (X, W) = (unpack_plan(spec, z) for z in plans)
    np.testing.assert_allclose(Xa[:3], X[:3], atol=1e-2)  # predicted positions (m)
    np.testing.assert_allclose(Wa[6:], W[6:], atol=1e-2)  # slacks
    assert X[2, 1:].min() >= 1.0 - 1e-4  # the hard floor holds along the plan
    assert W[6:, 1:].min() >= -1e-6  # slacks are non-negative


def test_size_mismatch_raises_instead_of_shifting_data():
    spec = ocp_spec(SC)
    ctrl = NMPC(spec)
    x = spec.vehicle.hover_state([0.0, 0.0, 3.0])
    P = spec.params.matrix(spec.horizon + 1, {"p_ref": [0, 0, 3.0], "v_ref": 0.0, "rho_d": [0, 0, 1.0], "psi_ref": 0.0, "p2": [1, 1, 3.0],
                                             "mu": 0.2, **weight_parameters(SC, spec)})
    with pytest.raises(ValueError, match="parameter matrix"):
        ctrl.step(x, np.zeros(6), P[:-1])
    with pytest.raises(ValueError, match="plant state has 18"):
        ctrl.step(x[:-1], np.zeros(6), P)
    with pytest.raises(ValueError, match="input 6"):
        ctrl.step(x, np.zeros(4), P)


def test_a_fleet_relays_p0_parameter_is_the_base_station_of_the_one_relay_ocp():
    """With ``p0_parameter`` the comms-aware terms look toward the stage parameter ``p0``: its residuals and
    constraint rows equal those of the one-relay OCP whose base station sits at that point."""
    from dataclasses import replace

    base = ocp_spec(SC)
    here = np.array([3.0, -4.0, 2.0])
    fixed = replace(base, bs_position=tuple(here))
    fleet = replace(base, p0_parameter=True)
    assert "p0" in fleet.params and "p0" not in base.params and fleet.key() != base.key()
    rng = np.random.default_rng(0)
    xa, w = rng.normal(size=fixed.nx), rng.normal(size=fixed.nw)
    p_fixed = rng.normal(size=fixed.n_params)
    p_fleet = np.zeros(fleet.n_params)
    for name in fixed.params.names:
        p_fleet[fleet.params[name]] = p_fixed[fixed.params[name]]
    p_fleet[fleet.params["p0"]] = here
    for f in ("stage_residual", "constraint_expr"):
        values = []
        for spec, p in ((fixed, p_fixed), (fleet, p_fleet)):
            X, W, P = ca.SX.sym("x", spec.nx), ca.SX.sym("w", spec.nw), ca.SX.sym("p", spec.n_params)
            values.append(np.array(ca.Function("f", [X, W, P], [getattr(spec, f)(X, W, P)])(xa, w, p)).ravel())
        np.testing.assert_allclose(values[1], values[0], rtol=1e-12, err_msg=f)


@pytest.mark.parametrize("kind", ["nominal", "quad", "fleet_relay"])
def test_an_ocp_rebuilt_from_its_description_is_the_same_problem(kind):
    """What a C tree's manifest.json carries (a peer solver in another process rebuilds the OCP from it): through JSON
    and back, the same key and the same expressions, evaluated at a random point."""
    import json

    sc = parse_scenario({"platform": {"rotor_count": 4, "tilt_deg": 0.0}}) if kind == "quad" else SC
    spec = ocp_spec(sc, neighbours=2, p0_parameter=True) if kind == "fleet_relay" else ocp_spec(sc, neighbours=1)
    again = OcpSpec.from_description(json.loads(json.dumps(spec.description())))
    assert again.key() == spec.key() and again.n_params == spec.n_params and again.ng == spec.ng
    rng = np.random.default_rng(3)
    xa, w, p = rng.normal(size=spec.nx), rng.normal(size=spec.nw), rng.normal(size=spec.n_params)
    def expressions(s: OcpSpec) -> ca.Function:
        x_, w_, p_ = s._symbols()
        return ca.Function("f", [x_, w_, p_], [s.discrete_dynamics(x_, w_, p_), s.stage_residual(x_, w_, p_),
                                               s.constraint_expr(x_, w_, p_)])

    f, g = expressions(spec), expressions(again)
    for a, b in zip(f(xa, w, p), g(xa, w, p), strict=True):
        np.testing.assert_array_equal(np.array(a), np.array(b))


def test_an_ocp_with_its_own_terms_is_not_described():
    spec = ocp_spec(SC)
    from dataclasses import replace

    with pytest.raises(ValueError, match="cost terms or constraints of its own"):
        replace(spec, constraints_all=CONSTRAINTS[:0]).description()
