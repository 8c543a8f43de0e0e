"""Relay networks in a scenario file: [[relays]], [[sources]], [network]; named errors for every
malformed network (issue: relay networks I)."""

from __future__ import annotations

import copy
import tomllib

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly import build_scene, parse_scenario
from aerorelay.config import ScenarioError

WPS = [[0.0, 30.0, 0.0, 5.0], [20.0, 40.0, 0.0, 8.0]]
WS = {"min": [-5.0, -10.0, 0.5], "max": [45.0, 10.0, 20.0]}


def chain(**network) -> dict:
    return {"controller": {"workspace": copy.deepcopy(WS), "planner": "capacity"},
            "relays": [{"name": "r1", "start": [20.0, 1.0, 5.0]}, {"name": "r2", "start": [10.0, -1.0, 5.0]}],
            "sources": [{"name": "inspector", "mission": {"waypoints": copy.deepcopy(WPS)}}],
            "network": {"routes": [["inspector", "r1", "r2", "bs"]], **network}}


def test_a_chain_reads_and_builds_its_scene():
    sc = parse_scenario(chain(min_separation_m=2.0))
    assert [r.name for r in sc.relay_list] == ["r1", "r2"] and sc.route_list == [["inspector", "r1", "r2", "bs"]]
    scene = build_scene(sc)
    assert scene.all_routes == (("inspector", "r1", "r2", "bs"),)
    assert scene.hops == (("inspector", "r1"), ("r1", "r2"), ("r2", "bs"))
    again = parse_scenario(tomllib.loads(sc.to_toml()))  # the resolved file reads back the same
    assert again == sc


def test_a_file_with_nodes_relay_is_one_relay_and_one_source():
    sc = ar.load_scenario("scenarios/nominal_tilted.toml")
    assert [r.name for r in sc.relay_list] == ["relay"] and [s.name for s in sc.source_list] == ["source"]
    assert sc.route_list == [["source", "relay", "bs"]] and sc.shape.plans == "relay" and "[network]" not in sc.to_toml()


def test_default_routes_go_through_every_relay_in_order():
    data = chain()
    data["network"] = {}
    assert parse_scenario(data).route_list == [["inspector", "r1", "r2", "bs"]]


def test_two_sources_sharing_two_relays():
    data = chain()
    data["sources"].append({"name": "second", "mission": {"waypoints": [[0.0, 30.0, 5.0, 6.0], [20.0, 35.0, 5.0, 6.0]]}})
    data["network"]["routes"].append(["second", "r1", "r2", "bs"])
    sc = parse_scenario(data)
    scene = build_scene(sc)
    assert len(scene.all_routes) == 2 and scene.route_hops() == ((0, 1, 2), (3, 1, 2))
    lines = dict(ar.api.link_budget_lines(sc))
    routes = [float(lines[f"route {r}: capacity alone"].split()[0]) for r in ("inspector -> r1 -> r2 -> bs",
                                                                             "second -> r1 -> r2 -> bs")]
    rate = float(lines["network rate (every source, each hop its own slot)"].split()[0])
    # R = B / sum_s sum_k 1/se = 1 / (1/C_1 + 1/C_2) when every hop counts once per route
    assert rate == pytest.approx(1.0 / (1.0 / routes[0] + 1.0 / routes[1]), rel=1e-3)


@pytest.mark.parametrize("change,message", [
    (lambda d: d["network"].update(routes=[["inspector", "r1", "r2"]]), r"network\.routes\[0\]: .* must end at a base station \(bs, any\)"),
    (lambda d: d["network"].update(routes=[["inspector", "r1", "rX", "bs"]]), r"network\.routes\[0\]: no node named 'rX'"),
    (lambda d: d["network"].update(routes=[["inspector", "r1", "r2", "r1", "bs"]]), r"network\.routes\[0\]: .* passes 'r1' twice \(a cycle\)"),
    (lambda d: d["network"].update(routes=[["r1", "r2", "bs"]]), r"network\.routes\[0\]: .* must start at a source \(inspector\)"),
    (lambda d: d["network"].update(routes=[["inspector", "r1", "bs"]]), r"relays\[1\]: 'r2' is on no route"),
    (lambda d: d["relays"].append({"name": "r1", "start": [30.0, 5.0, 5.0]}), r"network: \['r1'\] named more than once"),
    (lambda d: d["relays"][1].update(name="bs"), r"network: \['bs'\] named more than once"),
    (lambda d: d["network"].update(min_separation_m=3.0) or d["relays"][1].update(start=[18.5, 1.0, 5.0]),
     r"network\.min_separation_m: relays\[0\] \('r1'\) and relays\[1\] \('r2'\) start 1\.5 m apart, closer than the separation 3 m"),
    (lambda d: d["controller"]["workspace"].update(min=[0.0, 0.0, 0.5], max=[30.0, 2.0, 2.0]) or d["relays"][0].update(start=[1.0, 1.0, 1.0])
     or d["relays"][1].update(start=[29.0, 1.0, 1.0]) or d["relays"].append({"name": "r3", "start": [15.0, 1.0, 1.0]})
     or d["network"].update(routes=[["inspector", "r1", "r2", "r3", "bs"]])
     or d["network"].update(min_separation_m=16.0),
     r"network\.min_separation_m: controller\.workspace holds 2 vehicles 16 m apart \(a cubic lattice\), fewer than the 3 relays"),
    (lambda d: d.update(nodes={"relay": [1.0, 1.0, 1.0]}), r"nodes\.relay: give the relays as \[\[relays\]\] or one nodes\.relay"),
    (lambda d: d.update(mission={"waypoints": WPS}), r"mission: give the sources as \[\[sources\]\]"),
    (lambda d: d["relays"][0].update(start=[100.0, 0.0, 5.0]), r"relays\[0\]\.start \[100\.0, 0\.0, 5\.0\] must lie inside controller\.workspace"),
    (lambda d: d["relays"][0].update(platform="tricopter"), r"relays\.0\.platform: .*unknown platform preset 'tricopter'"),
    (lambda d: d["relays"][0].update(controller={"mu": 3.0}), r"relays\[0\]\.controller\.mu: Input should be less than or equal to 1"),
    (lambda d: d["relays"][0].update(controller={"mu": 0.3}), r"relays\[0\]\.controller\.mu: the network's planner plans every "
                                                              r"relay with one controller\.mu"),
    (lambda d: d["relays"][1].update(controller={"capacity": {"leash_m": 9.0}}),
     r"relays\[1\]\.controller\.capacity\.leash_m: the network's planner"),
    (lambda d: d["controller"].setdefault("capacity", {}).update(excursion_m=2.0), r"controller\.capacity\.excursion_m: only one "
                                                                         r"relay's capacity planner"),
    (lambda d: d["relays"][0].update(name="r 1"), r"relays\.0\.name"),
    (lambda d: d["relays"][1].update(controller={"horizon": 45}),
     r"relays\[1\]\.controller\.horizon: every relay of a fleet predicts on the shared controller\.horizon = 30 .* got 45"),
])
def test_a_malformed_network_is_a_named_error(change, message):
    data = chain()
    change(data)
    with pytest.raises(ScenarioError, match=message):
        parse_scenario(data)


def test_a_relay_flies_its_own_platform_and_controller():
    data = chain()
    data["relays"][0].update(platform="quad_x", controller={"governor_speed_m_s": 0.3, "weights": {"yaw": 2.0}})
    sc = parse_scenario(data)
    assert sc.platform_of(0).rotors is not None and sc.platform_of(1) == sc.platform
    assert sc.controller_of(0).governor_speed_m_s == 0.3 and sc.controller_of(0).weights.yaw == 2.0
    assert sc.controller_of(0).weights.position == sc.controller.weights.position and sc.controller_of(1) == sc.controller


def test_a_relay_on_an_own_platform_that_cannot_hover_is_named():
    data = chain()
    data["relays"][1]["platform"] = {"mass_kg": 30.0}
    with pytest.raises(ScenarioError, match=r"^relays\[1\]\.platform: hover infeasible"):
        parse_scenario(data)


def test_one_relay_written_as_a_network_parses_to_the_same_flight():
    """The nominal preset with its relay as [[relays]] and its mission as [[sources]]: the two spellings
    fly the same mission bit for bit, each vehicle's columns under its own name (``relay`` / ``r1``)."""
    data = tomllib.loads(open("scenarios/nominal_tilted.toml").read())
    data.setdefault("sim", {})["duration_s"] = 1.5
    legacy = parse_scenario(data)
    net = copy.deepcopy(data)
    net["relays"] = [{"name": "r1", "start": legacy.nodes.relay}]
    net["sources"] = [{"name": "inspector", "mission": net.pop("mission", {})}]
    net.get("nodes", {}).pop("relay", None)
    net["network"] = {"routes": [["inspector", "r1", "bs"]]}
    a, b = ar.simulate(legacy).timeseries, ar.simulate(parse_scenario(net)).timeseries
    b.columns = [c.replace("inspector", "source").replace("r1", "relay") for c in b.columns]
    assert list(a.columns) == list(b.columns)
    for c in a.columns:
        if not c.endswith("_ms"):
            assert a[c].equals(b[c]), c


def test_a_fleet_runs_from_the_command_line_with_its_network_bound(tmp_path):
    from typer.testing import CliRunner

    from aerorelay.cli import app

    f = tmp_path / "chain.toml"
    coarse = {**chain(), "bound": {"grid_m": 5.0, "dt_s": 10.0}, "sim": {"duration_s": 0.5}}  # the run reuses the bound
    f.write_text(parse_scenario(coarse).to_toml())
    res = CliRunner().invoke(app, ["bound", str(f), "--out", str(tmp_path / "b")])
    assert res.exit_code == 0 and "achieved" in res.output, res.output
    assert {"bound.json", "bound.parquet", "bound.png"} <= {p.name for p in (tmp_path / "b").iterdir()}
    res = CliRunner().invoke(app, ["run", str(f), "--out", str(tmp_path / "r"), "--duration", "0.5"])
    assert res.exit_code == 0, res.output
    import json
    m = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert 0 < m["capacity_efficiency_mean"] <= m["capacity_efficiency_mean_achieved"] and m["bound"]["relays"] == ["r1", "r2"]
    assert {"scenario.toml", "timeseries.parquet", "metrics.json", "capacity.png", "paths.png", "trajectory.html",
            "constraints_r1.png", "tracking_r2.png"} <= {
        p.name for p in (tmp_path / "r").iterdir()}
    res = CliRunner().invoke(app, ["report", str(tmp_path / "r")])
    assert res.exit_code == 0, res.output
    view = (tmp_path / "r" / "trajectory.html").read_text()
    assert all(f'"name":"{n}' in view.replace(": ", ":") for n in ("relay r1", "relay r2", "source inspector", "bs"))
    page = (tmp_path / "r" / "report.html").read_text()
    assert "relays.r2.position_error_mean_m" in page and "routes.inspector.c_mean" in page and page.count("<img") == 7
    res = CliRunner().invoke(app, ["info", str(f)])
    assert res.exit_code == 0 and "r1 -> r2: SINR" in res.output and "end-to-end capacity" in res.output, res.output


def test_a_sources_mission_file_is_named_relative_to_the_scenario_file(tmp_path):
    (tmp_path / "src.csv").write_text("t,px,py,pz\n" + "".join(f"{t},{30 + 0.5 * t},0.0,5.0\n" for t in range(6)))
    data = chain()
    data["sources"][0]["mission"] = {"trajectory_csv": "src.csv"}
    f = tmp_path / "chain.toml"
    f.write_text(parse_scenario({**data, "sources": [{"name": "inspector", "mission": {"trajectory_csv":
                                                                                       str(tmp_path / "src.csv")}}]})
                 .to_toml().replace(str(tmp_path / "src.csv"), "src.csv"))
    sc = ar.load_scenario(f)
    assert sc.source_list[0].mission.trajectory_csv == str((tmp_path / "src.csv").resolve())
    assert sc.duration_s == 5.0
    run = ar.simulate(ar.load_scenario(f, set={"sim.duration_s": 0.3}))
    run.save(tmp_path / "run", figures=False)  # the run folder holds the source's file and flies again
    assert (tmp_path / "run" / "mission_inspector.csv").read_text() == (tmp_path / "src.csv").read_text()
    again = ar.load_scenario(tmp_path / "run" / "scenario.toml")
    assert again.source_list[0].mission.trajectory_csv == str((tmp_path / "run" / "mission_inspector.csv").resolve())


def test_one_relay_written_as_a_network_gets_its_bound_and_its_capacity_planner():
    """A one-relay network file names its relay (r1), not 'relay': the single-relay bound's grid and the
    capacity planner's compiled grid place that node (they looked for 'relay': a KeyError)."""
    data = tomllib.loads(open("scenarios/nominal_tilted.toml").read())
    data.setdefault("sim", {})["duration_s"] = 1.0
    data["relays"] = [{"name": "r1", "start": data.get("nodes", {}).pop("relay", [-6.95, 5.79, 1.72])}]
    data["sources"] = [{"name": "inspector", "mission": data.pop("mission", {})}]
    data["controller"] = {**data.get("controller", {}), "planner": "capacity"}
    data["bound"] = {"grid_m": 1.0, "dt_s": 0.5}
    r = ar.simulate(parse_scenario(data), bound=True)
    assert not r.metrics["unsafe"] and 0 < r.metrics["capacity_efficiency_mean"] <= 1.05


def test_a_networks_old_spellings_are_read_as_the_one_field_and_two_values_are_refused(caplog):
    """``network.planner``, ``network.route_dt_s``, ``bound.network_grid_m`` and ``bound.network_dt_s`` (the network's
    spellings before 2026-12-05) are read as ``controller.planner``, ``controller.capacity.route_dt_s``,
    ``bound.grid_m`` and ``bound.dt_s`` with a warning naming both; one setting spelled twice with two values is a
    named error; with the same value it is read once."""
    def unplanned(**network) -> dict:
        d = chain(**network)
        del d["controller"]["planner"]
        return d

    old = {**unplanned(planner="capacity", route_dt_s=4.0), "bound": {"network_grid_m": 5.0, "network_dt_s": 10.0}}
    new = unplanned()
    new["controller"] |= {"planner": "capacity", "capacity": {"route_dt_s": 4.0}}
    new["bound"] = {"grid_m": 5.0, "dt_s": 10.0}
    with caplog.at_level("WARNING"):
        a = parse_scenario(copy.deepcopy(old))
    b = parse_scenario(new)
    assert a.model_dump() == b.model_dump()
    assert (a.planner, a.route_dt_s, a.bound_grid_m, a.bound_dt_s) == ("capacity", 4.0, 5.0, 10.0)
    # a network's defaults, and one relay's, from the one field left unset
    plain = parse_scenario(unplanned())
    assert (plain.planner, plain.route_dt_s, plain.bound_grid_m, plain.bound_dt_s) == ("equidistant", 2.0, 2.0, 2.0)
    nominal = ar.load_scenario("scenarios/nominal_tilted.toml")
    assert (nominal.planner, nominal.route_dt_s, nominal.bound_grid_m, nominal.bound_dt_s) == \
        ("trajectory_generator", 1.0, 0.5, 0.5)
    twice = unplanned(planner="capacity")
    twice["controller"]["planner"] = "equidistant"
    with pytest.raises(ScenarioError, match=r"network\.planner = 'capacity' and controller\.planner = 'equidistant': one "
                                            r"setting spelled twice"):
        parse_scenario(twice)
    same = unplanned(planner="paper")
    same["controller"]["planner"] = "trajectory_generator"
    assert parse_scenario(same).planner == "trajectory_generator"


HETEROGENEOUS = {"quad": {"platform": "quad_x", "speed": 0.4, "governor": 0.3},
                 "hexa": {"platform": "hexa_tilted", "speed": 1.6, "governor": 0.9}}


@pytest.mark.parametrize("planner", ["equidistant", "capacity", "trajectory_generator"])
def test_a_heterogeneous_chain_flies_each_relays_reference_within_its_own_speed_limit(planner):
    """A quadrotor and a tilted hexarotor in one chain, each with its own platform, speed limit (and the paper's
    generator's governor speed) and antenna: every planner moves each relay's reference at most at its own limit (+1%),
    and the fast relay's reference moves faster than the slow one's limit (the shared limit is not flown)."""
    data = chain()
    data["controller"]["planner"] = planner
    data["sim"] = {"duration_s": 3.0}
    data["jammer"] = {"position": [15.0, -8.0, 2.0], "power_w": 4.0}
    data["network"]["min_separation_m"] = 2.0
    for r, (name, own) in zip(data["relays"], HETEROGENEOUS.items(), strict=True):
        r.update(name=name, platform=own["platform"],
                 controller={"capacity": {"speed_m_s": own["speed"]}, "governor_speed_m_s": own["governor"]})
    data["relays"][0]["antenna"] = {"pattern": "sin_power", "exponent": 2.0}
    data["network"]["routes"] = [["inspector", "quad", "hexa", "bs"]]
    sc = parse_scenario(data)
    r = ar.simulate(sc, bound=False)
    df = r.timeseries
    dt = np.diff(df.t.to_numpy())
    fastest = {}
    for name, own in HETEROGENEOUS.items():
        p = df[[f"{name}.pd_{a}" for a in "xyz"]].to_numpy()
        fastest[name] = float((np.linalg.norm(np.diff(p, axis=0), axis=1) / dt).max())
        limit = own["governor"] if planner == "trajectory_generator" else own["speed"]
        assert fastest[name] <= limit * 1.01, (name, fastest[name], limit)
    assert fastest["hexa"] > HETEROGENEOUS["quad"]["speed" if planner != "trajectory_generator" else "governor"] * 1.05, fastest
