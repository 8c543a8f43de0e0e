"""``aerorelay bench`` of a fleet: each relay's step, the planner's and the fleet's two ways, their
sums checked against each other and against the run's own log."""

from __future__ import annotations

import copy
import json

import numpy as np
from typer.testing import CliRunner

import aerorelay as ar
from aerorelay.assembly import parse_scenario
from aerorelay.cli import app

from ..sim.test_fleet import CHAIN


def test_a_fleets_bench_times_each_relay_the_planner_and_the_fleet(tmp_path):
    d = copy.deepcopy(CHAIN)
    d["sim"]["duration_s"] = 1.0
    d["relays"][0]["lost_at_s"] = 0.5  # a lost relay times nothing after
    res = ar.bench(parse_scenario(d))
    steps = res["steps"]
    assert steps == 67 and set(res["relays"]) == {"r1", "r2"}
    assert res["relays"]["r2"]["steps"] == steps and res["relays"]["r1"]["steps"] == 34  # lost at 0.5 s: steps 0..33
    for r in res["relays"].values():
        assert r["step_ms"]["max"] >= r["feedback_ms"]["max"] > 0
    one, own = res["fleet_step_one_computer_ms"], res["fleet_step_own_computers_ms"]
    # the mean of per-step sums is the sum of the parts' means (each over the steps it ran)
    total = sum(r["step_ms"]["mean"] * r["steps"] for r in res["relays"].values()) / steps + res["planner_ms"]["mean"]
    assert np.isclose(one["mean"], total, rtol=1e-9)
    assert own["mean"] <= one["mean"] and own["max"] >= res["relays"]["r2"]["step_ms"]["max"]


def test_bench_prints_a_fleets_table_and_writes_its_json(tmp_path):
    d = copy.deepcopy(CHAIN)
    d["sim"]["duration_s"] = 0.5
    path = tmp_path / "chain.toml"
    path.write_text(parse_scenario(d).to_toml())
    out = CliRunner().invoke(app, ["bench", str(path), "--json", str(tmp_path / "b.json")])
    assert out.exit_code == 0, out.output
    assert "r1: step" in out.output and "fleet, a computer per relay" in out.output
    assert json.loads((tmp_path / "b.json").read_text())["relays"]["r2"]["steps"] == 34
