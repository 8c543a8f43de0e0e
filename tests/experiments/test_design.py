"""Issue 79, item 4: ``aerorelay design``: relay counts and schedules as a campaign, the relays placed by the tool,
each point flown with its bound and against the direct link; the recommendation is the best flown of those tried
(or the direct link), written as a scenario that loads; bad input refused before any work."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import aerorelay as ar
from aerorelay.cli import app
from aerorelay.experiments.design import parse_relays, placed_relays

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()


def test_relay_counts_are_parsed_or_refused_by_name():
    assert parse_relays("1-3") == [1, 2, 3] and parse_relays("2") == [2] and parse_relays("1,4,2") == [1, 2, 4]
    for bad in ("0-2", "a", "3-1", "17", ""):
        with pytest.raises(ValueError, match=r"--relays: .*from 1 to 16"):
            parse_relays(bad)


@pytest.mark.parametrize("k", [1, 3, 6])
def test_the_placed_relays_lie_on_the_line_apart_and_inside_the_workspace(k):
    sc = ar.load_scenario(ROOT / "scenarios" / "long_inspection.toml")
    starts = np.array([r["start"] for r in placed_relays(sc, k)])
    gap = sc.separation_m + 0.5
    assert [r["name"] for r in placed_relays(sc, k)] == [f"r{i + 1}" for i in range(k)]
    ws = sc.controller.workspace
    assert np.all(starts >= np.array(ws.min) + 0.5 - 1e-9) and np.all(starts <= np.array(ws.max) - 0.5 + 1e-9)
    # on one horizontal line from the base station at the origin (toward the inspection's far end, +x), r1 farthest out
    xy = starts[:, :2]
    assert np.allclose(xy[:, 0] * xy[0, 1] - xy[:, 1] * xy[0, 0], 0.0, atol=0.2) and np.all(np.diff(xy[:, 0]) < 0)
    assert np.min(np.linalg.norm(np.diff(starts, axis=0), axis=1), initial=np.inf) >= gap - 1e-9
    src = np.array(sc.source_list[0].mission.start)
    assert np.all(np.linalg.norm(starts - src, axis=1) >= gap - 1e-9)


def test_a_design_flies_every_point_and_recommends_the_best_flown(tmp_path):
    out = tmp_path / "design"
    args = ["design", str(ROOT / "scenarios" / "long_inspection.toml"), "--out", str(out), "--relays", "1,2", "--schedule", "tdma",
            "--schedule", "full_duplex", "--duration", "1", "--no-bound", "--workers", "1"]
    r = runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    d = json.loads((out / "design.json").read_text())
    assert {(p["relays"], p["schedule"]) for p in d["points"]} == {(k, s) for k in (1, 2) for s in ("tdma", "full_duplex")}
    assert all(p["flown"]["exit_status"] == "complete" for p in d["points"]) and not d["missing"]
    best = max([p["flown"]["c_mean"] for p in d["points"]] + [d["direct"]["c_mean"]])
    assert d["recommended"]["c_mean"] == best  # the best flown of those tried (the direct link among them)
    if d["recommended"]["relays"]:
        rec = ar.load_scenario(out / "recommended.toml")
        assert len(rec.relay_list) == d["recommended"]["relays"] and rec.network.schedule == d["recommended"]["schedule"]
    assert (out / "design.png").stat().st_size > 0
    # resumed: nothing flown again, the same design
    again = runner.invoke(app, args)
    assert again.exit_code == 0 and json.loads((out / "design.json").read_text())["recommended"] == d["recommended"]


def test_bad_design_input_is_refused_before_any_work(tmp_path):
    base = ["design", str(ROOT / "scenarios" / "long_inspection.toml"), "--out", str(tmp_path / "d")]
    for extra, said in ((["--relays", "0"], "--relays"), (["--schedule", "csma"], "--schedule"), (["--by", "mean"], "--by")):
        r = runner.invoke(app, base + extra)
        assert r.exit_code == 2 and said in r.output, r.output
        assert not (tmp_path / "d").exists()
