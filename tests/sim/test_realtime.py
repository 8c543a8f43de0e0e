"""The cyclic garbage collector's full collections are held off during the control loop only."""

import gc

import pytest

from aerorelay.assembly import parse_scenario
from aerorelay.assembly.parts import build
from aerorelay.control.bench import collections_counted
from aerorelay.planning.fleet import held_reference
from aerorelay.sim.realtime import full_collections_paused


def test_thresholds_are_restored_after_the_block_even_on_an_error():
    before = gc.get_threshold()
    with pytest.raises(RuntimeError), full_collections_paused():
        assert gc.get_threshold()[:2] == before[:2]
        assert gc.get_threshold()[2] > 10**6  # no automatic full collection in the block
        raise RuntimeError("a failing step")
    assert gc.get_threshold() == before


def test_no_automatic_full_collection_runs_during_a_mission():
    """A planner wrapper records the collector's threshold at every step, and the collections the
    loop triggers are counted by generation: young ones run, full ones do not."""
    sc = parse_scenario({}).with_updates({"sim.duration_s": 2.0})
    seen, full = [], []

    class Recording:  # a one-relay planner holding the relay where it is, recording the collector's threshold
        def update(self, inp):
            seen.append(gc.get_threshold()[2])
            return held_reference(inp.p1)

    def count(phase, info):
        if phase == "stop" and info["generation"] == 2:
            full.append(info)

    before = gc.get_threshold()
    gc.collect()
    gc.callbacks.append(count)
    try:
        gc.set_threshold(50, 1, 1)  # without the pause: a full collection every other young one
        build(sc, planner=Recording()).closed_loop().run()
    finally:
        gc.callbacks.remove(count)
        gc.set_threshold(*before)
    assert seen and min(seen) > 10**6
    assert not full


def test_collections_are_counted_per_generation_and_the_counter_removed():
    out: dict = {}
    n_callbacks = len(gc.callbacks)
    with collections_counted(out):
        gc.collect(0)
        gc.collect(2)
        gc.collect(2)
    assert out["collections"] == [1, 0, 2]
    assert out["max_ms"][2] >= out["max_ms"][1] == 0.0 and out["max_ms"][2] > 0.0
    assert len(gc.callbacks) == n_callbacks
