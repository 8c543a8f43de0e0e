"""pytest-benchmark timings of the controller (run with ``pytest tests/bench --benchmark-enable -n 0``:
one process, as the suite runs on pytest-xdist).

In the normal suite ``--benchmark-disable`` runs each body once as a smoke test; speed targets are
read from these benchmarks and from ``aerorelay bench``, never asserted in unit tests.
"""

import numpy as np
import pytest

from aerorelay.assembly import parse_scenario
from aerorelay.assembly.parts import build
from aerorelay.models.radio import NodePose
from aerorelay.planning.fleet import FleetInput


@pytest.fixture(scope="module", params=["constrained", "unconstrained"])
def loop_mid_mission(request):
    sc = parse_scenario({}).with_updates({"controller.variant": request.param, "sim.duration_s": 9.0})
    loop = build(sc).closed_loop()
    loop.run()
    loop.nmpc = loop.relays[0].controller.nmpc  # the one relay's NMPC, as it stopped mid-mission
    return loop


def test_bench_rti_step(benchmark, loop_mid_mission):
    bp = loop_mid_mission.bench_points["relay"][0]
    x, u, P = bp.x, bp.u_prev, bp.P
    nmpc = loop_mid_mission.nmpc
    info = benchmark(nmpc.step, x, u, P, False)
    assert info.ok and np.all(np.isfinite(info.u))


def test_bench_feedback_phase(benchmark, loop_mid_mission):
    """The latency that matters on hardware: measurement in, input out (preparation done before)."""
    bp = loop_mid_mission.bench_points["relay"][0]
    x, u, P = bp.x, bp.u_prev, bp.P
    nmpc = loop_mid_mission.nmpc

    def feedback():
        nmpc.prepare(P, u)
        return nmpc.feedback(x, u, False)

    info = benchmark(feedback)
    assert info.ok


def test_bench_trajectory_generator(benchmark, loop_mid_mission):
    loop = loop_mid_mission
    src = loop.sources["source"].state(9.0)
    inp = FleetInput(t=9.0, dt=0.015, positions={"relay": src.p + 1.0, "source": src.p}, velocities={"source": src.v},
                     accelerations={"source": src.a}, jammer_positions=loop.scene.jammers[0].position[None],
                     jammer_powers=np.ones(1))
    refs = benchmark(loop.planner.update, inp)  # the paper's generator, for the one relay
    assert np.all(np.isfinite(refs["relay"].p_ref))


@pytest.fixture(scope="module")
def capacity_planner():
    sc = parse_scenario({}).with_updates({"controller.planner": "capacity"})
    parts = build(sc)
    return parts.relay_planner, parts.scene


@pytest.mark.parametrize("route", ["compiled", "numpy"])
def test_bench_capacity_planner_scoring(benchmark, capacity_planner, route):
    """One replan's scoring, 27 positions x every holdable axis: the compiled relay grid against
    the numpy evaluation of the same scene."""
    planner, scene = capacity_planner
    cand = np.array([-4.0, 2.0, 5.0]) + planner.offsets
    pose = NodePose(np.array([-1.0, 4.3, 9.0]), np.array([0.0, 0.0, 1.0]))
    pj, PJ = scene.jammers[0].position[None], np.ones(1)
    if route == "compiled":
        C = benchmark(planner.grid, cand, planner.axes, pose, pj, PJ)
    else:
        C = benchmark(scene.relay_grid, 0.0, cand, planner.axes, {planner.source_name: pose}, jammer_positions=pj,
                      jammer_powers=PJ)
    assert C.shape == (27, len(planner.axes)) and np.all(np.isfinite(C))
