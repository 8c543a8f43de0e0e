"""Planners see what the relay knows, never the truth the plant holds: they are built from the
scene's world view, whose jammers have no true position, path or power; a planner in estimated
mode cannot reach the true jammer positions, and a channel evaluated without the known positions
fails loudly instead of turning a study into an oracle study."""

from pathlib import Path

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.models.jammer import HiddenJammer, JammerTruthHidden
from aerorelay.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]


def _arrays_reachable(obj, seen=None, depth=0):
    """Every numpy array reachable from ``obj`` through attributes, dicts, lists and tuples."""
    seen = set() if seen is None else seen
    if id(obj) in seen or depth > 12:
        return
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        yield obj
        return
    if isinstance(obj, dict):
        children = list(obj.values())
    elif isinstance(obj, list | tuple | set | frozenset):
        children = list(obj)
    elif hasattr(obj, "__dict__") and not isinstance(obj, type):
        children = list(vars(obj).values())
    elif hasattr(obj, "__slots__"):
        children = [getattr(obj, s) for s in obj.__slots__ if hasattr(obj, s)]
    else:
        return
    for c in children:
        yield from _arrays_reachable(c, seen, depth + 1)


@pytest.mark.parametrize("planner", ["trajectory_generator", "capacity"])
def test_a_planner_in_estimated_mode_cannot_reach_the_true_jammer_positions(planner):
    sc = load_scenario(ROOT / "scenarios" / "nominal_tilted.toml",
                       set={"jammer.position": [-5.3, -4.1, 2.3], "jammer.localization": "estimated", "controller.planner": planner,
                            "sim.duration_s": 0.3})
    parts = ar.build(sc)
    true = np.array([-5.3, -4.1, 2.3])
    assert np.allclose(parts.scene.jammers[0].position_at(0.0), true)  # the plant's scene holds the truth
    leaks = [a for a in _arrays_reachable(parts.planner) if a.shape[-1:] == (3,) and np.any(np.all(np.isclose(
        a.reshape(-1, 3), true), axis=1))]
    assert not leaks, "the planner holds the true jammer position"
    assert all(isinstance(j, HiddenJammer) for j in _jammers_reachable(parts.planner))
    from aerorelay.scenario.build import planner_context

    ctx = planner_context(sc, parts.vehicle, parts.scene, parts.source)
    assert ctx.scene.jammers and all(isinstance(j, HiddenJammer) for j in ctx.scene.jammers)


def _jammers_reachable(obj):
    seen, stack = set(), [obj]
    while stack:
        o = stack.pop()
        if id(o) in seen:
            continue
        seen.add(id(o))
        if isinstance(o, ar.Jammer):
            yield o
            continue
        if isinstance(o, dict):
            stack.extend(o.values())
        elif isinstance(o, list | tuple):
            stack.extend(o)
        elif hasattr(o, "__dict__") and not isinstance(o, type | np.ndarray):
            stack.extend(vars(o).values())


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
