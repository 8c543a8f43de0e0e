"""The plant's ray-traced channel (``sim/traced.py``) in the closed loop: an empty scene flies the free-space
mission (the line of sight carried between traces exactly); in the street canyon the logged capacity at
every tracing step is recomputed from a new trace of the logged poses, each path weighed here by the
half-wave dipole's pattern (paper App. A, written out) toward its directions. Needs the ``rt`` extra."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly import load_scenario, parse_scenario
from aerorelay.assembly.load import updated
from aerorelay.assembly.parts import build, build_scene
from aerorelay.config import ScenarioError
from aerorelay.models.geometry import rotation_batch
from aerorelay.models.raytrace import RayTracer, TraceSettings
from tests.reference_channel import end_to_end_capacity
from tests.rt_marks import needs_rt

ROOT = Path(__file__).resolve().parents[2]
PHYSICAL = {"sim.duration_s": 2.0, "channel.units": "physical", "jammer.power_dbm": 0.0}


def dipole(c):
    """Half-wave dipole power gain, ``cos(pi/2 cos th)^2 / sin(th)^2`` (paper App. A, normalized)."""
    c = np.clip(c, -1.0, 1.0)
    return np.where(1 - c * c > 1e-12, np.cos(np.pi / 2 * c) ** 2 / np.maximum(1 - c * c, 1e-12), 0.0)


@needs_rt
def test_an_empty_scene_flies_the_free_space_mission():
    base = parse_scenario({}).with_updates(PHYSICAL)
    free = build(base).closed_loop().run().log
    traced = build(base.with_updates({"channel.propagation.model": "ray_traced", "channel.propagation.scene": "empty"})
                   ).closed_loop().run().log
    for col in ("sinr.source.relay", "sinr.relay.bs", "capacity"):
        np.testing.assert_allclose(traced[col], free[col], rtol=1e-5)
    np.testing.assert_array_equal(free["relay.p_x"], traced["relay.p_x"])  # the controllers never see the traced channel
    age = traced["trace_age_s"]
    assert np.sum(age == 0) == 8 and np.max(age) == pytest.approx(0.24, abs=0.01)  # traced every 0.25 s (15 ms steps)
    # one path: no delay spread (up to the rounding of its variance: 6e-7 ns seen)
    assert np.all(traced["paths_relay_bs"] == 1) and np.all(np.abs(traced["delay_spread_ns_relay_bs"]) < 1e-3)


@needs_rt
def test_the_street_canyons_logged_capacity_is_recomputed_from_a_new_trace_of_the_logged_poses():
    sc = load_scenario(ROOT / "scenarios" / "street_canyon.toml").with_updates({"sim.duration_s": 1.0})
    log = build(sc).closed_loop().run().log
    scene = build_scene(sc)
    P_U, P_J = 0.1, scene.jammers[0].power
    N = 1.380649e-23 * 290 * 20e6 * 10 ** 0.7
    at = np.flatnonzero(log["trace_age_s"] == 0)
    assert len(at) == 4
    tracer = RayTracer(TraceSettings("simple_street_canyon", 2.4e9, max_depth=3), cached=False)

    def pos(name):
        return np.column_stack([log[f"{name}.p_x"], log[f"{name}.p_y"], log[f"{name}.p_z"]])[at]

    def axis(name):
        return rotation_batch(np.column_stack([log[f"{name}.phi"], log[f"{name}.theta"], log[f"{name}.psi"]])[at])[:, :, 2]

    p1, p2, b1, b2 = pos("relay"), pos("source"), axis("relay"), axis("source")
    n = len(at)
    p0, pj = np.tile([-50.0, 0.0, 6.0], (n, 1)), np.tile([0.0, -6.0, 1.5], (n, 1))
    up = np.tile([0.0, 0.0, 1.0], (n, 1))

    def gain(tx, b_tx, rx, b_rx, iso_tx=False):  # power sum of the traced paths, each weighed by both dipoles
        links = tracer.trace(tx, rx)
        g_t = np.ones(links.valid.shape) if iso_tx else dipole(np.einsum("npi,ni->np", links.departure, b_tx))
        g_r = dipole(np.einsum("npi,ni->np", links.arrival, b_rx))
        return np.sum(np.where(links.valid, np.abs(links.a) ** 2 * g_t * g_r, 0.0), axis=1)

    g21 = gain(p2, b2, p1, b1) * P_U / (gain(pj, up, p1, b1, iso_tx=True) * P_J + N)
    g10 = gain(p1, b1, p0, up) * P_U / (gain(pj, up, p0, up, iso_tx=True) * P_J + N)
    np.testing.assert_allclose(log["sinr.source.relay"][at], g21, rtol=1e-6)
    np.testing.assert_allclose(log["sinr.relay.bs"][at], g10, rtol=1e-6)
    np.testing.assert_allclose(log["capacity"][at], end_to_end_capacity(g21, g10, 20e6), rtol=1e-6)
    assert np.all(log["paths_relay_bs"][at] > 1)  # reflections off the street's walls and floor


@pytest.mark.parametrize("updates, fragment", [
    ({"channel.propagation.model": "ray_traced"}, "channel.propagation.scene"),
    ({"channel.propagation.model": "ray_traced", "channel.propagation.scene": "empty", "channel.units": "normalized"},
     "channel.units = 'physical'"),
])
def test_bad_ray_traced_settings_are_named(updates, fragment):
    with pytest.raises(ScenarioError, match=re.escape(fragment)):
        parse_scenario({}).with_updates({**PHYSICAL, **updates})


@needs_rt
def test_an_unknown_scene_is_named_before_any_work():
    with pytest.raises(ScenarioError, match=r"channel\.propagation\.scene: .*no scene 'atlantis'"):
        updated(parse_scenario({}), {**PHYSICAL, "channel.propagation.model": "ray_traced",
                                     "channel.propagation.scene": "atlantis"})


@needs_rt
def test_a_fleet_flies_on_the_traced_channel_as_one_relay_does():
    """The two-relay chain in an empty scene: every hop's SINR and the network's rate as in free space (the traced
    line of sight carried between traces exactly), its three hops and the jammer's links traced in one call."""
    chain = ar.load_scenario(ROOT / "scenarios" / "chain_two_relays.toml").with_updates({"sim.duration_s": 1.0})
    free = build(chain).closed_loop().run().log
    loop = build(chain.with_updates({"channel.propagation.model": "ray_traced", "channel.propagation.scene": "empty"})).closed_loop()
    traced = loop.run().log
    for col in ("sinr.inspector.r1", "sinr.r1.r2", "sinr.r2.bs", "capacity"):
        np.testing.assert_allclose(traced[col], free[col], rtol=1e-5)
    assert loop.traced is not None and loop.traced.traces == 4  # 1 s at one trace per 0.25 s
