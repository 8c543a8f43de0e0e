import numpy as np
import pytest

from aerorelay.assembly import parse_scenario
from aerorelay.assembly.parts import ocp_spec, weight_parameters
from aerorelay.assembly.vehicle import build_vehicle
from aerorelay.control.full_nlp import FullNlp
from aerorelay.control.nmpc import NMPC, NmpcSettings
from aerorelay.control.ocp import unpack_plan
from aerorelay.sim.closed_loop import plant_step_function

SC = parse_scenario({})
SPEC = ocp_spec(SC)
VEH = SPEC.vehicle
HOME = np.array([-5.0, 4.0, 2.0])  # a geometry where the alignment constraint is inactive
P2 = np.array([-2.0, 4.0, 2.5])


@pytest.fixture(scope="module", params=["hpipm", "casadi"])
def nmpc(request):
    return NMPC(SPEC, NmpcSettings(backend=request.param))


@pytest.fixture(scope="module")
def plant():
    return plant_step_function(build_vehicle(SC.platform), SC.sim.plant_rate_hz, SC.control_period_s)


def params(p_ref, v_ref=np.zeros(3), p2=P2, sc=SC, spec=SPEC):
    """Stage parameters through the spec's named layout (MRAV-2 held at p2, level thrust reference)."""
    tk = spec.ts * np.arange(spec.horizon + 1)
    return spec.params.matrix(spec.horizon + 1, {
        "p_ref": p_ref[:, None] + v_ref[:, None] * tk, "v_ref": v_ref, "rho_d": [0.0, 0.0, 1.0], "psi_ref": 0.0, "p2": p2,
        "mu": sc.controller.mu, **weight_parameters(sc, spec)})


def fly(nmpc, plant, x, steps, ref_fn):
    nmpc.reset(np.concatenate([x, np.zeros(6)]))
    u = np.zeros(6)
    hist = []
    for k in range(steps):
        info = nmpc.step(x, u, ref_fn(k))
        assert info.ok, info.status
        u = info.u
        x = np.asarray(plant(x, u, np.zeros(6))).ravel()
        hist.append((x.copy(), u.copy()))
    return x, hist


def test_hover_recovered_from_perturbed_state(nmpc, plant):
    x = VEH.hover_state(HOME)
    x[0:3] += [0.1, -0.1, 0.05]
    x[3:6] = np.radians([5.0, -5.0, 3.0])
    x[9:12] = [0.2, -0.2, 0.1]
    x, hist = fly(nmpc, plant, x, 400, lambda k: params(HOME))
    assert np.linalg.norm(x[0:3] - HOME) < 0.05
    assert np.abs(np.degrees(x[3:5])).max() < 1.0
    assert np.abs(x[6:12]).max() < 0.05


def test_ramp_reference_tracked(nmpc, plant):
    # a 1 m step fed at 0.5 m/s, as the reference governor does, then held
    goal = HOME + np.array([1.0, 0.0, 0.0])
    v = 0.5 * (goal - HOME) / np.linalg.norm(goal - HOME)
    n_ramp = int(2.0 / SPEC.ts)

    def ref(k):
        if k < n_ramp:
            return params(HOME + v * k * SPEC.ts, v)
        return params(goal)

    x, hist = fly(nmpc, plant, VEH.hover_state(HOME), n_ramp + 300, ref)
    assert np.linalg.norm(x[0:3] - goal) < 0.05


def test_bounds_respected_during_aggressive_manoeuvre(nmpc, plant):
    x, hist = fly(nmpc, plant, VEH.hover_state(HOME), 200, lambda k: params(HOME + np.array([3.0, -3.0, 2.0])))
    speeds = np.array([h[0][12:] for h in hist])
    inputs = np.array([h[1] for h in hist])
    assert speeds.min() >= VEH.omega_min - 1e-6 and speeds.max() <= VEH.omega_max + 1e-6
    assert inputs.min() >= VEH.omega_dot_min - 1e-9 and inputs.max() <= VEH.omega_dot_max + 1e-9


def test_rti_converges_to_ipopt_solution(nmpc):
    x = VEH.hover_state(HOME)
    u = np.zeros(6)
    P = params(HOME + np.array([0.3, -0.2, 0.1]), p2=np.array([-2.0, 1.0, 12.0]))
    nmpc.reset(np.concatenate([x, u]))
    for _ in range(40):
        nmpc.step(x, u, P, shift=False)
    z_rti = nmpc.guess()
    lbz, ubz = nmpc.absolute_bounds()
    z_ip, ok = FullNlp(SPEC).solve(np.concatenate([x, u]), P, z_rti, lbz, ubz)
    assert ok
    nx = SPEC.nx
    np.testing.assert_allclose(z_rti[nx : nx + 6], z_ip[nx : nx + 6], rtol=0.01, atol=0.05)  # first input
    pos = lambda z: unpack_plan(SPEC, z)[0][:3, : SPEC.horizon]
    np.testing.assert_allclose(pos(z_rti), pos(z_ip), atol=1e-3)


def _assert_fallback(nmpc, info, before):
    assert not info.ok and nmpc.failures == before + 1
    assert np.all(np.isfinite(info.u))
    assert np.all(info.u >= VEH.omega_dot_min) and np.all(info.u <= VEH.omega_dot_max)


def test_qp_failure_is_counted_and_answered_with_fallback(nmpc, monkeypatch):
    x = VEH.hover_state(HOME)
    nmpc.reset(np.concatenate([x, np.zeros(6)]))
    nmpc.step(x, np.zeros(6), params(HOME))
    before = nmpc.failures
    if nmpc.settings.backend == "casadi":
        real_qp = nmpc.engine.qp

        class NanQp:
            """The real QP whose solution comes back as NaN (as a silently failing solver would)."""

            def __call__(self, **kw):
                out = real_qp(**kw)
                out["x"] = out["x"] * np.nan
                return out

            def stats(self):
                return real_qp.stats()

        monkeypatch.setattr(nmpc.engine, "qp", NanQp())
        info = nmpc.step(x, np.zeros(6), params(HOME))
    else:  # the compiled engine: a NaN parameter poisons the QP data
        P = params(HOME)
        P[SPEC.params["p_ref"], 5] = np.nan
        info = nmpc.step(x, np.zeros(6), P)
    _assert_fallback(nmpc, info, before)
    monkeypatch.undo()
    # the controller recovers on the next well-posed problem
    assert nmpc.step(x, info.u, params(HOME)).ok


def test_iteration_limit_is_a_failure_with_fallback():
    nmpc = NMPC(SPEC, NmpcSettings(iter_max=1))
    x = VEH.hover_state(HOME)
    x[0:3] += 0.5
    info = nmpc.step(x, np.zeros(6), params(HOME))
    assert info.status == "MAX_ITER"
    _assert_fallback(nmpc, info, 0)


def test_a_capped_qp_is_used_only_when_its_primal_residuals_pass_the_check(plant):
    """iter_max = 1 with accept_tol: the first interior-point iterate is primal feasible (HPIPM's
    Riccati step satisfies the linearized dynamics) and is flown; an iterate that fails the check
    (1e-300) continues from itself to the uncapped solution (``iter_continue``), or, with no
    continuation, makes the same QP a failure, as without a cap check."""
    x = VEH.hover_state(HOME)
    x[0:3] += 0.5
    capped = NMPC(SPEC, NmpcSettings(iter_max=1, accept_tol=1e-6))
    info = capped.step(x, np.zeros(6), params(HOME))
    assert info.ok and info.status == "CAPPED" and np.all(np.isfinite(info.u))
    strict = NMPC(SPEC, NmpcSettings(iter_max=1, accept_tol=1e-300, iter_continue=0))
    assert strict.step(x, np.zeros(6), params(HOME)).status == "MAX_ITER"
    continued = NMPC(SPEC, NmpcSettings(iter_max=1, accept_tol=1e-300)).step(x, np.zeros(6), params(HOME))
    full = NMPC(SPEC, NmpcSettings()).step(x, np.zeros(6), params(HOME))
    assert continued.ok and continued.status == "SUCCESS" and continued.qp_iters > 1
    np.testing.assert_allclose(continued.u, full.u, rtol=1e-3, atol=1e-3 * np.abs(full.u).max())
    # a cap of a few iterations flies like the uncapped solver (one iterate alone is feasible
    # but too timid: 200 steps leave 0.51 of the 0.87 m offset, 3 or 50 iterations 0.47)
    ends = [fly(NMPC(SPEC, NmpcSettings(iter_max=n, accept_tol=1e-6)), plant, x.copy(), 200, lambda k: params(HOME))[0]
            for n in (3, 50)]
    assert np.linalg.norm(ends[0][0:3] - ends[1][0:3]) < 0.01
    assert np.linalg.norm(ends[1][0:3] - HOME) < 0.6 * np.linalg.norm(x[0:3] - HOME)  # on its way back


@pytest.mark.parametrize("updates", [{}, {"controller.variant": "unconstrained"}, {"controller.exact_input_rate": False}],
                         ids=["constrained", "unconstrained", "lagged_input_rate"])
def test_compiled_engine_solves_the_same_qp_as_casadi_conic(updates):
    """Same guess, same parameters, tight tolerances: the two QP routes take the same step
    (the engine removes the fixed initial-state and stage-0 slack variables; the solution must not change)."""
    tight = dict(tol_comp=1e-7, iter_max=200)
    sc = SC.with_updates(updates)
    spec = ocp_spec(sc)
    a, b = NMPC(spec, NmpcSettings(backend="casadi", **tight)), NMPC(spec, NmpcSettings(backend="hpipm", **tight))
    home = np.array([0.0, 0.0, 5.0])
    x = VEH.hover_state(home)
    x[3:6] = np.radians([4.0, -3.0, 10.0])
    P = params(home + np.array([0.5, 0.3, -0.2]), p2=np.array([3.0, 1.0, 8.0]), sc=sc, spec=spec)
    P[spec.params["mu"]] = 0.5  # the alignment constraint is active along the horizon
    infos = []
    for ctrl in (a, b):
        ctrl.reset(np.concatenate([x, np.zeros(6)]) if spec.exact_input_rate else x)
        infos.append(ctrl.step(x, np.zeros(6), P, shift=False))
    assert all(i.ok for i in infos)
    # casadi.conic's HPIPM stops on its own residual criteria (5 iterations on the unconstrained QP,
    # where the engine's answer moves by < 1e-5 relative between tol 1e-7 and 1e-10): 1e-4 relative,
    # 0.02 Hz/s absolute (5e-5 of the input range)
    np.testing.assert_allclose(infos[0].u, infos[1].u, rtol=1e-4, atol=2e-2)
    assert infos[0].slack_max == pytest.approx(infos[1].slack_max, rel=1e-5, abs=1e-9)
    za, zb = a.guess(), b.guess()
    pos = lambda z: unpack_plan(spec, z)[0][:12, : spec.horizon]
    np.testing.assert_allclose(pos(za), pos(zb), atol=5e-4)  # positions, attitudes, velocities, rates


def test_alignment_constraint_acts_only_in_constrained_variant(plant):
    from aerorelay.models.channel import misalignment, mutual_alignment
    from aerorelay.models.geometry import rotation_zyx

    steep = np.array([-2.0, 1.0, 5.0])  # BS link 66 deg below the horizon: level mutual alignment 0.16 < mu
    p2 = np.array([1.0, 3.0, 6.0])
    result = {}
    for variant in ("constrained", "unconstrained"):
        sc = SC.with_updates({"controller.variant": variant})
        spec = ocp_spec(sc)
        ctrl = NMPC(spec)
        P = params(steep, p2=p2, sc=sc, spec=spec)
        x, _ = fly(ctrl, plant, VEH.hover_state(steep), 200, lambda k, P=P: P)
        R = rotation_zyx(x[3:6])
        result[variant] = mutual_alignment(misalignment(x[:3], R, p2), misalignment(x[:3], R, np.zeros(3)))
    assert result["unconstrained"] < 0.17
    assert result["constrained"] >= SC.controller.mu - 0.02


def test_without_a_c_compiler_the_controller_falls_back_to_casadi(monkeypatch, caplog):
    import aerorelay.control.nmpc as nmpc_module
    import aerorelay.store.codegen as codegen

    monkeypatch.setattr(codegen, "cache_dir", lambda: __import__("pathlib").Path("/nonexistent-cache"))
    monkeypatch.setattr(codegen.shutil, "which", lambda name: None)
    ctrl = nmpc_module.NMPC(SPEC, NmpcSettings(backend="hpipm"))
    assert isinstance(ctrl.engine, nmpc_module.ConicEngine)
    assert "casadi.conic route" in caplog.text
    x = VEH.hover_state(HOME)
    assert ctrl.step(x, np.zeros(6), params(HOME)).ok


@pytest.mark.parametrize("field,value", [("backend", "acados"), ("warm_start", "hot"), ("riccati", "lu"), ("tol_comp", 0.0)])
def test_bad_settings_are_named(field, value):
    with pytest.raises(ValueError, match=f"NmpcSettings.{field}"):
        NmpcSettings(**{field: value})


def test_unpack_plan_inverts_pack_plan():
    from aerorelay.control.ocp import pack_plan, unpack_plan

    rng = np.random.default_rng(0)
    X, W = rng.normal(size=(SPEC.nx, SPEC.horizon + 1)), rng.normal(size=(SPEC.nw, SPEC.horizon))
    Xu, Wu = unpack_plan(SPEC, pack_plan(X, W))
    np.testing.assert_array_equal(Xu, X)
    np.testing.assert_array_equal(Wu, W)


def test_bench_times_ipopt_also_for_the_lagged_input_rate():
    from aerorelay.assembly.parts import build
    from aerorelay.control.bench import benchmark_closed_loop

    sc = SC.with_updates({"controller.exact_input_rate": False, "sim.duration_s": 4.0})
    res = benchmark_closed_loop(build(sc).closed_loop(), ipopt_points=1)
    assert res["ipopt_converged"] == "1/1" and res["qp_failures"] == 0
    assert res["garbage_collections"]["collections"][2] == 0  # no full collection inside the flight


def test_sensitivity_feedback_matches_a_solve_for_the_measured_state():
    """The preparation solves at the predicted state; the feedback's first-order correction for a
    measured state 1 cm / 1 cm/s off agrees with a full solve to < 1e-3 Hz/s, and the error
    shrinks with the offset (the correction is the solution's derivative, not a fixed gain)."""
    x = VEH.hover_state(HOME)
    x[3:6] = np.radians([4.0, -3.0, 10.0])
    P = params(HOME + np.array([0.5, 0.3, -0.2]), p2=np.array([3.0, 1.0, 8.0]))
    errors, moves = [], []
    for off in (1e-2, 1e-3):
        us = []
        for fb in ("solve", "sensitivity"):
            c = NMPC(SPEC, NmpcSettings(feedback=fb, tol_comp=1e-8, iter_max=100))
            c.reset(np.concatenate([x, np.zeros(6)]))
            for _ in range(5):
                u_pred = c.step(x, np.zeros(6), P, shift=False).u
            x2 = x.copy()
            x2[0:3] += off
            x2[6:9] += off
            info = c.step(x2, np.zeros(6), P, shift=False)
            assert info.ok
            us.append(info.u)
        errors.append(np.abs(us[0] - us[1]).max())
        moves.append(np.abs(us[0] - u_pred).max())
    assert errors[0] < 1e-3 and errors[1] < 0.2 * errors[0]
    assert moves[1] > 100 * errors[1]  # the correction is most of the input's change
    assert NMPC(SPEC).route().count("sensitivity feedback") == 1


def test_sensitivity_feedback_needs_the_uncondensed_engine():
    with pytest.raises(ValueError, match="NmpcSettings.feedback"):
        NmpcSettings(feedback="sensitivity", backend="casadi")
    assert NmpcSettings(backend="casadi").feedback == "solve" and NmpcSettings().feedback == "sensitivity"


def test_ocps_that_differ_only_in_the_workspace_share_one_library_and_each_keeps_its_own(plant):
    """The engine's library is keyed by its C source alone; the workspace is not in it (its bounds reach the engine
    when it is made), so a scenario that moves its walls compiles nothing, and each engine keeps its own walls:
    told to climb 3 m, the relay under a ceiling 0.5 m above it stops there (2.50005 m measured), the one without
    climbs past it (3.10 m in the 150 steps)."""
    from dataclasses import replace

    from aerorelay.control.hpipm_rti import build_library
    ceiling = HOME[2] + 0.5
    low = replace(SPEC, workspace_max=(*SPEC.workspace_max[:2], ceiling))
    assert build_library(low) == build_library(SPEC)
    heights = {}
    for name, spec in (("low", low), ("high", SPEC)):
        _, hist = fly(NMPC(spec, NmpcSettings(backend="hpipm")), plant, VEH.hover_state(HOME), 150,
                      lambda k, spec=spec: params(HOME + np.array([0.0, 0.0, 3.0]), spec=spec))
        heights[name] = max(h[0][2] for h in hist)
    assert heights["low"] <= ceiling + 0.02 < ceiling + 0.5 < heights["high"]


@pytest.mark.parametrize("compile_it,kind", [(True, "External"), (False, "MXFunction")])
def test_the_casadi_route_compiles_its_preparation_only_when_told(compile_it, kind):
    """``NmpcSettings.compile`` on the casadi.conic route: a compiled library, or CasADi's own function."""
    assert NMPC(SPEC, NmpcSettings(backend="casadi", compile=compile_it)).engine.prep.class_name() == kind
