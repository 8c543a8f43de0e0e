"""A relay lost in flight (``[[relays]] lost_at_s``): from then on it is gone, every route through it
skips it, the others re-plan; the logged rate equals the link equations on the smaller chain's logged
poses; its metrics cover what it flew; the bound splices the smaller fleet's bound in from the loss."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly import parse_scenario
from aerorelay.assembly.parts import build_scene
from aerorelay.config import ScenarioError
from aerorelay.planning.network_bound import NetworkBound, spliced

from .test_fleet import CHAIN, _recompute, two_sources

LOSS_S = 1.0


def lost(data: dict, name: str = "r1", t: float = LOSS_S) -> dict:
    d = copy.deepcopy(data)
    next(r for r in d["relays"] if r["name"] == name)["lost_at_s"] = t
    return d


def test_a_loss_before_the_start_is_a_named_error_and_one_after_the_end_does_not_happen():
    d = copy.deepcopy(CHAIN)
    d["relays"][0]["lost_at_s"] = -1.0
    with pytest.raises(ScenarioError, match=r"relays\.0\.lost_at_s"):
        parse_scenario(d)
    # issue 45: --duration 3 on a scenario that loses a relay at 30 s was refused; the flight ends first
    sc = parse_scenario(lost(CHAIN, t=2.0))
    assert sc.duration_s == 2.0 and sc.losses == [] and sc.relay_list[0].lost_at_s == 2.0
    assert parse_scenario(lost(CHAIN, t=1.0)).losses == [(1.0, frozenset({"r1"}))]


def test_losing_every_relay_or_a_jammers_target_is_a_named_error():
    with pytest.raises(ScenarioError, match=r"relays\[1\]\.lost_at_s: every relay would be lost"):
        parse_scenario(lost(lost(CHAIN), "r2"))
    d = lost(CHAIN)
    d["jammer"] |= {"point_at": "r1", "pattern": "cosine"}
    with pytest.raises(ScenarioError, match=r"jammer\.point_at: 'r1' is lost at 1 s"):
        parse_scenario(d)


def test_the_scene_without_a_relay_skips_it_on_every_route_and_keeps_the_jammers():
    sc = parse_scenario(two_sources())
    scene = build_scene(sc)
    smaller = scene.without({"r1"})
    assert smaller.all_routes == (("inspector", "r2", "bs"), ("second", "r2", "bs"))
    assert smaller.hops == (("inspector", "r2"), ("r2", "bs"), ("second", "r2"))  # route order, a shared hop once
    assert "r1" not in [n.name for n in smaller.nodes]
    assert [j.power for j in smaller.jammers] == [j.power for j in scene.jammers]
    one = scene.without({"r1", "r2"})  # both routes become direct links, kept apart
    assert one.all_routes == (("inspector", "bs"), ("second", "bs"))
    merged = build_scene(parse_scenario(CHAIN)).without({"r2"})
    assert merged.all_routes == (("inspector", "r1", "bs"),) and merged.routes == ()
    sc2 = sc.without_relays(frozenset({"r1"}))
    assert [r.name for r in sc2.relay_list] == ["r2"] and sc2.route_list == [["inspector", "r2", "bs"], ["second", "r2", "bs"]]
    assert sc2.losses == []


@pytest.fixture(scope="module")
def flown():
    sc = parse_scenario(lost(CHAIN))
    return sc, ar.simulate(sc)


def test_after_the_loss_the_rate_is_the_smaller_chains_on_the_logged_poses(flown):
    sc, r = flown
    df, m = r.timeseries, r.metrics
    assert not m["unsafe"], m["unsafe_reason"]
    before, after = df[df.t < LOSS_S], df[df.t >= LOSS_S]
    assert len(before) and len(after)
    assert after["r1.p_x"].isna().all() and (after["r1.qp_status"] == "lost").all() and before["r1.p_x"].notna().all()
    assert after["sinr.inspector.r1"].isna().all() and after["sinr.r1.r2"].isna().all()
    assert before["sinr.inspector.r2"].isna().all()
    jp = sc.jammer_configs[0].power_w
    for routes, rows in (([["inspector", "r1", "r2", "bs"]], before), ([["inspector", "r2", "bs"]], after)):
        for _, row in rows.iloc[[0, -1]].iterrows():
            gamma, _, rate = _recompute(row, routes, jp)
            for (tx, rx), g in gamma.items():
                assert row[f"sinr.{tx}.{rx}"] == pytest.approx(g, rel=1e-9)
            assert row["capacity"] == pytest.approx(rate, rel=1e-9)
    assert m["losses"] == [{"t_s": LOSS_S, "relays": ["r1"]}]
    assert m["relays"]["r1"]["lost_at_s"] == LOSS_S
    assert m["c_mean_before_loss"] == pytest.approx(before["capacity"].mean(), rel=1e-12)
    assert m["c_min_after_loss"] == pytest.approx(after["capacity"].min(), rel=1e-12)
    assert m["separation_min_m"] >= sc.network.min_separation_m
    assert math.isfinite(m["relays"]["r1"]["position_error_mean_m"]) and math.isfinite(m["fleet_solve_ms"]["mean"])


def test_the_survivor_replans_toward_its_place_on_the_smaller_chain(flown):
    """Equidistant planner: r2 was 1/3 of the way from the base station to the inspector; alone, its
    place is halfway, and its reference heads there from where it was."""
    sc, r = flown
    df = r.timeseries
    after = df[df.t >= LOSS_S]
    first, last = after.iloc[0], after.iloc[-1]
    src = np.array([last["inspector.p_x"], last["inspector.p_y"], last["inspector.p_z"]])
    half = 0.5 * (src + np.array(sc.nodes.bs))
    p_ref = lambda row: np.array([row["r2.pd_x"], row["r2.pd_y"], row["r2.pd_z"]])  # noqa: E731
    assert np.linalg.norm(p_ref(last) - half) < np.linalg.norm(p_ref(first) - half) - 0.5  # 1 m/s for ~1 s
    assert (after["r2.qp_status"] != "lost").all() and after["r2.qp_ok"].mean() > 0.9


def _bound(t, static, relays, value):
    T, K = len(t), len(relays)
    return NetworkBound(t, np.full(T, static), np.full((T, K, 3), value), np.full(T, static - 1), np.full((T, K, 3), value),
                        np.full((T, K, 3), value), relays, {"cells": 10 * K})


def test_the_spliced_bound_is_the_smaller_fleets_from_the_loss_on():
    t = np.arange(0.0, 10.1, 2.0)
    b = spliced([(0.0, _bound(t, 5.0, ["r1", "r2"], 1.0)), (4.0, _bound(t, 7.0, ["r2"], 2.0))])
    np.testing.assert_array_equal(b.static, [5, 5, 7, 7, 7, 7])
    np.testing.assert_array_equal(b.achieved, [4, 4, 6, 6, 6, 6])
    assert b.relays == ["r1", "r2"]
    assert np.isnan(b.static_positions[2:, 0]).all() and (b.static_positions[:2, 0] == 1.0).all()
    assert (b.achieved_positions[2:, 1] == 2.0).all() and (b.achieved_axes[:2, 1] == 1.0).all()
    assert [p["relays"] for p in b.resolution["phases"]] == [["r1", "r2"], ["r2"]]
