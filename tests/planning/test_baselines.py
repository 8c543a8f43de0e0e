import numpy as np
import pytest

from aerorelay.assembly import parse_scenario
from aerorelay.assembly.parts import build, build_scene
from aerorelay.models.geometry import E3, attitude_from_thrust, rotation_zyx
from aerorelay.models.mission import source_trajectory
from aerorelay.planning.baselines import PlannedReference, SingleShotPlanner
from aerorelay.planning.fleet import FleetInput
from aerorelay.planning.trajectory_generator import TrajectoryGenerator
from tests.reference_channel import end_to_end_capacity, link_sinr

SC = parse_scenario({})


@pytest.fixture(scope="module")
def plan():
    return SingleShotPlanner(build_scene(SC), dt=1.0).plan(source_trajectory(SC.mission), np.array(SC.nodes.relay), 20.0,
                                                           SC.controller.workspace.min, SC.controller.workspace.max)


def real_mean_capacity(plan, dt):
    """Independent recomputation of the planner's objective with the numpy channel model (no jammer)."""
    src = source_trajectory(SC.mission)
    caps = []
    for k, t in enumerate(plan.t):
        s = src.state(t)
        R2 = rotation_zyx(attitude_from_thrust(s.a + 9.81 * E3))
        a1 = (plan.p[k - 1] - 2 * plan.p[k] + plan.p[k + 1]) / dt**2 if 0 < k < len(plan.t) - 1 else np.zeros(3)
        R1 = rotation_zyx(attitude_from_thrust(a1 + 9.81 * E3))
        kw = dict(tx_power=1.0, jam_power=0.0, noise_power=1.0)
        g21 = link_sinr(s.p, R2, plan.p[k], R1, np.zeros(3), **kw)
        g10 = link_sinr(plan.p[k], R1, np.zeros(3), np.eye(3), np.zeros(3), **kw)
        caps.append(end_to_end_capacity(g21, g10))
    return float(np.mean(caps))


def test_single_shot_plan_is_feasible_and_beats_hovering(plan):
    assert plan.success
    steps = np.linalg.norm(np.diff(plan.p, axis=0), axis=1)
    assert steps.max() <= 0.5 * 1.0 + 1e-6
    np.testing.assert_allclose(plan.p[0], SC.nodes.relay)
    ws = SC.controller.workspace
    assert np.all(plan.p >= np.array(ws.min) - 1e-6) and np.all(plan.p <= np.array(ws.max) + 1e-6)
    ours = real_mean_capacity(plan, 1.0)
    assert ours == pytest.approx(plan.mean_capacity, rel=1e-3)
    hover = type(plan)(plan.t, np.tile(plan.p[0], (len(plan.t), 1)), 0.0, True)
    assert ours > real_mean_capacity(hover, 1.0)


def test_planned_reference_interpolates(plan):
    ref = PlannedReference(plan)
    r = ref.update(plan.t[3])
    np.testing.assert_allclose(r.p_ref, plan.p[3], atol=1e-9)
    assert np.linalg.norm(r.a_ref) <= 2.0 + 1e-9
    np.testing.assert_allclose(ref.update(1e6).p_ref, plan.p[-1], atol=1e-9)


def test_baseline_a_plans_with_isotropic_surrogate():
    iso = SC.with_updates({"controller.planner": "isotropic", "controller.variant": "unconstrained"})
    assert build(iso).planner.sp.mu == 1.0  # H_bar = G_bar / d: the surrogate with mu = 1
    assert build(SC).planner.sp.mu == SC.controller.mu


def test_every_planner_answers_through_one_interface():
    """The closed loop never branches on planner names: each registered planner of the one relay returns its Reference
    from the same FleetInput (baseline B from its plan, made once, without a generator)."""
    short = SC.with_updates({"sim.duration_s": 4.0})
    src = source_trajectory(short.mission)
    s = src.state(1.0)
    p1 = np.array(short.nodes.relay)
    inp = FleetInput(t=1.0, dt=0.015, positions={"relay": p1, "source": s.p}, velocities={"relay": np.zeros(3), "source": s.v},
                     accelerations={"source": s.a}, jammer_positions=np.array([short.jammer.position]), jammer_powers=np.ones(1))
    for name in ("trajectory_generator", "isotropic", "single_shot"):
        sc = short.with_updates({"controller.planner": name})
        planner = build(sc).planner
        refs = planner.update(inp)
        assert list(refs) == ["relay"], name
        ref = refs["relay"]
        assert ref.p_ref.shape == (3,) and np.all(np.isfinite(ref.p_ref)), name
        assert isinstance(planner, TrajectoryGenerator) == (name != "single_shot"), name
        if name != "single_shot":  # the reference governor: the first reference at most governor_speed * dt from the relay
            assert np.linalg.norm(ref.p_ref - p1) <= sc.controller.governor_speed_m_s * inp.dt + 1e-9, name
