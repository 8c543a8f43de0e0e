"""Planners see what the relay knows, never the truth the plant holds: they are built from the
scene's world view, whose jammers have no true position, path or power; a planner in estimated
mode cannot reach the true jammer positions, and a channel evaluated without the known positions
fails loudly instead of turning a study into an oracle study."""

from pathlib import Path

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly import load_scenario
from aerorelay.models.jammer import HiddenJammer, JammerTruthHidden

ROOT = Path(__file__).resolve().parents[2]


def _reachable(obj):
    """Every object reachable from ``obj`` through attributes, dicts, lists and tuples (numpy arrays
    and jammers are yielded, not entered)."""
    seen, stack = set(), [obj]
    while stack:
        o = stack.pop()
        if id(o) in seen:
            continue
        seen.add(id(o))
        yield o
        if isinstance(o, np.ndarray | ar.Jammer | type):
            continue
        if isinstance(o, dict):
            stack.extend(o.values())
        elif isinstance(o, list | tuple | set | frozenset):
            stack.extend(o)
        elif hasattr(o, "__dict__"):
            stack.extend(vars(o).values())


@pytest.mark.parametrize("planner", ["trajectory_generator", "capacity"])
def test_a_planner_in_estimated_mode_cannot_reach_the_true_jammer_positions(planner):
    sc = load_scenario(ROOT / "scenarios" / "nominal_tilted.toml",
                       set={"jammer.position": [-5.3, -4.1, 2.3], "jammer.localization": "estimated", "controller.planner": planner,
                            "sim.duration_s": 0.3})
    parts = ar.build(sc)
    true = np.array([-5.3, -4.1, 2.3])
    assert np.allclose(parts.scene.jammers[0].position_at(0.0), true)  # the plant's scene holds the truth
    arrays = [a for a in _reachable(parts.planner) if isinstance(a, np.ndarray) and a.dtype.kind == "f"]
    leaks = [a for a in arrays if a.shape[-1:] == (3,) and np.any(np.all(np.isclose(a.reshape(-1, 3), true), axis=1))]
    assert not leaks, "the planner holds the true jammer position"
    assert all(isinstance(j, HiddenJammer) for j in _reachable(parts.planner) if isinstance(j, ar.Jammer))
    from aerorelay.assembly.parts import planner_context

    ctx = planner_context(sc, parts.relay("relay").vehicle, parts.scene, parts.sources["source"])
    assert ctx.scene.jammers and all(isinstance(j, HiddenJammer) for j in ctx.scene.jammers)


def test_the_world_view_keeps_what_the_relay_models_and_hides_the_truth():
    sc = load_scenario(ROOT / "scenarios" / "directional_jammer.toml")
    scene = ar.build_scene(sc)
    view = scene.world_view()
    for true, seen in zip(scene.jammers, view.jammers, strict=True):
        assert isinstance(seen, HiddenJammer) and seen.name == true.name and seen.pattern == true.pattern
        assert seen.point_at == true.point_at and np.allclose(seen.boresight, true.boresight)
        with pytest.raises(JammerTruthHidden, match=true.name):
            seen.position_at(1.0)
        with pytest.raises(JammerTruthHidden):
            seen.power_at(1.0)
    poses = {"relay": view.pose("relay", np.array(sc.nodes.relay), np.eye(3)),
             "source": view.pose("source", np.array(sc.mission.start), np.eye(3))}
    with pytest.raises(JammerTruthHidden):  # the forgotten keyword is an error, not an oracle
        view.evaluate(0.0, poses)
    known = np.array([j.position_at(0.0) for j in scene.jammers])
    powers = np.array([j.power for j in scene.jammers])
    a = view.evaluate(0.0, poses, jammer_positions=known, jammer_powers=powers).capacity
    b = scene.evaluate(0.0, poses, jammer_positions=known, jammer_powers=powers).capacity
    assert a == b  # given what the relay knows, the view is the same channel
