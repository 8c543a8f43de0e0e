"""Networks that hold as they grow (issue 76): long chains fly on their NMPCs, a relay's separation rows are the
nearest vehicles' and bounded, the verdict says when a relay's controller did not fly it, and a relay's own
workspace is checked at load, by the network's planners and in the verdict.

The chains are generated from their geometry (``experiments.chains``: relays evenly spaced on the line from the
base station to an inspection drone far out, two jammers beside the way, physical units). On main before the fix
(b4a026c) the five-relay 250 m capacity chain flew 92 / 71 / 98% of three relays' steps on the brake law and read
``complete``: its separation rows read 1.7e3-3.2e4 m^2 and the QPs ended at their iteration cap."""

from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from typer.testing import CliRunner

import aerorelay as ar
from aerorelay.api import read_metrics
from aerorelay.assembly import parse_scenario
from aerorelay.cli import EXIT_FELL_BACK, app
from aerorelay.config import ScenarioError
from aerorelay.control.network import UNUSED_ROW_OFFSET_M, separation_rows
from aerorelay.control.terms import separation_margin
from aerorelay.experiments.chains import long_chain
from aerorelay.experiments.run import run_metrics

ROOT = Path(__file__).parents[2]
BASE = ROOT / "scenarios" / "long_inspection.toml"


@pytest.mark.parametrize(("relays", "length_m", "planner"), [(3, 150.0, "equidistant"), (5, 250.0, "capacity"),
                                                             (8, 300.0, "equidistant")])
def test_a_long_chain_flies_every_relay_on_its_nmpc(relays, length_m, planner):
    sc = long_chain(BASE, relays, length_m, duration_s=3.0, updates={"controller.planner": planner})
    assert len(sc.relay_list) == relays
    # the geometry the generator promises: the relays evenly spaced on the line to the drone's start (a metre to its
    # sides), r1 farthest, the line as long as asked
    start = np.asarray(sc.source_list[0].mission.start)[:2]
    along = [float(np.dot(np.asarray(r.start[:2]), start / np.linalg.norm(start))) for r in sc.relay_list]
    assert np.allclose(np.diff(along), -np.linalg.norm(start) / (relays + 1), atol=0.05)
    assert np.linalg.norm(np.asarray(sc.source_list[0].mission.waypoints[-1][1:3])) == pytest.approx(length_m, abs=0.05)
    m = ar.simulate(sc).metrics
    assert m["exit_status"] == "complete" and not m["unsafe"] and not m["fell_back"]
    for name, r in m["relays"].items():
        assert r["fallback_fraction"] == 0.0, name
        assert r["infeasible_fraction"] == 0.0, name
    assert m["worst_relay_fallback_fraction"] == 0.0


def test_the_separation_row_is_zero_at_the_separation_with_the_squared_margin_s_slope_and_bounded():
    d = 2.1
    assert separation_margin(d * d, d * d) == 0.0
    h = 1e-6  # d/dr of the row at r = d: the squared margin's 2 d
    slope = (separation_margin((d + h) ** 2, d * d) - separation_margin((d - h) ** 2, d * d)) / (2 * h)
    assert slope == pytest.approx(2 * d, rel=1e-6)
    far = separation_margin(UNUSED_ROW_OFFSET_M**2, d * d)
    assert 2 * d * d * (1 - 1e-5) < far < 2 * d * d  # a vehicle a kilometre away: nearly constant, below 2 d^2
    assert separation_margin(0.0, d * d) == -2 * d * d


@given(r=st.floats(0.0, 1e4), d=st.floats(0.1, 100.0))
def test_the_separation_row_keeps_the_squared_margin_s_sign_and_stays_within_two_d_squared(r, d):
    row, squared = separation_margin(r * r, d * d), r * r - d * d
    assert abs(row) <= 2 * d * d
    assert (row > 0) == (squared > 0) and (row < 0) == (squared < 0)


def test_a_relay_s_rows_are_the_vehicles_whose_paths_come_nearest():
    N = 5
    own = np.zeros((3, N + 1))
    line = np.linspace(0.0, 1.0, N + 1)
    others = {"far": np.tile([[50.0], [0.0], [0.0]], N + 1),
              "crossing": np.vstack([10.0 - 9.0 * line, np.zeros(N + 1), np.zeros(N + 1)]),  # ends 1 m away
              "near": np.tile([[3.0], [0.0], [0.0]], N + 1),
              "close": np.tile([[0.0], [3.5], [0.0]], N + 1)}
    rows, kept, unguarded = separation_rows(own, others, 2, separation_m=2.0)
    assert kept == ["crossing", "near"]  # 1 m and 3 m at their nearest; "close" (3.5 m) left out
    assert np.array_equal(rows[:3], others["crossing"]) and np.array_equal(rows[3:], others["near"])
    assert unguarded == ["close"]  # within twice the separation (4 m) yet in no row: counted
    rows, kept, unguarded = separation_rows(own, {"near": others["near"]}, 3, separation_m=2.0)
    assert kept == ["near"] and unguarded == []
    assert np.allclose(rows[3:6], own - [[0.0], [0.0], [UNUSED_ROW_OFFSET_M]])  # an empty row looks far below
    assert np.allclose(rows[6:], rows[3:6])


def test_a_relay_s_nmpc_has_rows_for_the_nearest_vehicles_only():
    sc = long_chain(BASE, 8, 300.0, duration_s=1.0, updates={"controller.planner": "equidistant"})
    parts = ar.build(sc)
    assert {r.controller.spec.neighbours for r in parts.relays} == {sc.network.separation_neighbours}
    assert sc.network.separation_neighbours < len(sc.relay_list)  # 8 other vehicles, 4 rows
    with pytest.raises(ScenarioError, match="network.separation_neighbours"):  # nothing to leave out: it changes nothing
        long_chain(BASE, 2, 150.0, updates={"network.separation_neighbours": 3})


def test_a_relay_whose_qps_cannot_succeed_makes_the_run_fell_back(tmp_path):
    """One interior-point iteration cannot solve the capacity planner's tracking QP: the brake law flies most of
    the run, which is safe but not the controller's: exit status fell_back, exit 4, the relay's shares in the table."""
    out = tmp_path / "run"
    r = CliRunner().invoke(app, ["run", str(ROOT / "scenarios" / "nominal_tilted.toml"), "--out", str(out), "--no-bound",
                                 "--no-figures", "--duration", "2", "--set", "controller.planner=\"capacity\"",
                                 "--set", "controller.capacity.qp_iter_max=1"])
    assert r.exit_code == EXIT_FELL_BACK, r.output
    m = read_metrics(out)
    assert m["exit_status"] == "fell_back" and not m["unsafe"] and m["fell_back"]
    assert m["fallback_fraction"] > 0.05 and "verdict.fallback_fraction_max" in m["fell_back_reason"]
    assert m["relays"]["relay"]["exit_status"] == "fell_back"
    assert "fallback_fraction" in r.output and "fell back" in r.output
    # the threshold is the user's: at 1 the same flight reads complete
    out2 = tmp_path / "run2"
    r = CliRunner().invoke(app, ["run", str(ROOT / "scenarios" / "nominal_tilted.toml"), "--out", str(out2), "--no-bound",
                                 "--no-figures", "--duration", "2", "--set", "controller.planner=\"capacity\"",
                                 "--set", "controller.capacity.qp_iter_max=1", "--set", "verdict.fallback_fraction_max=1.0"])
    assert r.exit_code == 0, r.output
    assert read_metrics(out2)["exit_status"] == "complete"


CHAIN = {"sim": {"duration_s": 0.3}, "controller": {"workspace": {"min": [-5.0, -10.0, 0.5], "max": [45.0, 12.0, 20.0]}},
         "jammer": {"position": [15.0, -8.0, 2.0], "power_w": 4.0},
         "relays": [{"name": "r1", "start": [20.0, 1.0, 5.0]}, {"name": "r2", "start": [10.0, -1.0, 5.0]}],
         "sources": [{"name": "inspector", "mission": {"waypoints": [[0.0, 30.0, 0.0, 5.0], [20.0, 40.0, 0.0, 8.0]]}}],
         "network": {"min_separation_m": 2.0}}


def _own_box(box: dict) -> dict:
    d = copy.deepcopy(CHAIN)
    d["relays"][0]["controller"] = {"workspace": box}
    return d


def test_a_relay_s_own_workspace_is_checked_at_load_by_name():
    with pytest.raises(ScenarioError, match=r"relays\[0\].start .* inside relays\[0\].controller.workspace"):
        parse_scenario(_own_box({"min": [-5.0, -10.0, 0.5], "max": [3.0, 8.0, 6.0]}))


def test_a_relay_s_own_workspace_is_the_one_the_verdict_checks():
    """r1 flown, then its logged path moved 3 m beyond its own box (still inside [controller.workspace]): the verdict
    reads r1's box, not the network's."""
    sc = parse_scenario(_own_box({"min": [15.0, -5.0, 0.5], "max": [25.0, 5.0, 10.0]}))
    result = ar.simulate(sc)
    assert not result.metrics["unsafe"]
    mission = result.mission
    log = dict(mission.log)
    log["r1.p_x"] = np.asarray(log["r1.p_x"], float) + (25.0 + 3.0 - float(np.max(log["r1.p_x"])))
    mission.log = log
    vehicles = {r.name: ar.build(sc).relays[i].vehicle for i, r in enumerate(sc.relay_list)}
    m = run_metrics(sc, mission, vehicles, None)
    assert m["unsafe"] and m["relays"]["r1"]["exit_status"] == "left_workspace"
    assert m["relays"]["r1"]["box_violation_max_m"] == pytest.approx(3.0, abs=1e-9)
    assert not m["relays"]["r2"]["unsafe"]


def test_the_network_s_planner_keeps_each_relay_in_its_own_workspace():
    """The equidistant place of r1 is 20 m out; its own box ends at x = 16: the planner's goal stops inside it
    (margin 0.05 m), without the reference check clipping it."""
    d = _own_box({"min": [12.0, -5.0, 0.5], "max": [16.0, 5.0, 10.0]})
    d["relays"][0]["start"], d["relays"][1]["start"] = [15.0, 1.0, 5.0], [8.0, -1.0, 5.0]
    d["controller"]["planner"], d["sim"]["duration_s"] = "equidistant", 3.0
    result = ar.simulate(parse_scenario(d))
    goal_x = float(result.timeseries["r1.pd_x"].max())
    assert goal_x <= 16.0 - 0.05 + 1e-9
    assert not math.isclose(goal_x, 20.0)
    assert result.metrics["relays"]["r1"].get("reference_clipped_steps", 0) == 0


def test_relays_stepped_on_threads_fly_the_same_flight_bit_for_bit(monkeypatch):
    sc = long_chain(BASE, 4, 200.0, duration_s=1.0, updates={"controller.planner": "capacity"})
    logs = {}
    for threads in ("1", "3"):
        monkeypatch.setenv("AERORELAY_RELAY_THREADS", threads)
        log = ar.simulate(sc).timeseries
        logs[threads] = log.drop(columns=[c for c in log.columns if c.endswith(("solve_ms", "feedback_ms"))])
    assert logs["1"].equals(logs["3"])
    monkeypatch.setenv("AERORELAY_RELAY_THREADS", "many")
    with pytest.raises(ValueError, match="AERORELAY_RELAY_THREADS must be a whole number"):
        ar.simulate(sc)
