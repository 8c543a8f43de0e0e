"""A run folder holds everything to fly it again: only the mission source that flew, a CSV
mission copied beside it with a relative path, and re-flying its scenario.toml gives the same run."""

import tomllib

import numpy as np
import pandas as pd
from typer.testing import CliRunner

import aerorelay as ar
from aerorelay.cli import app
from aerorelay.models.mission import MinimumJerkPath

TIMING = {"relay.solve_ms", "relay.feedback_ms"}  # wall-clock measurements: the only columns a re-flight may change


def _csv_mission(path):
    src = MinimumJerkPath([[0.0, -3.04, 5.79, 1.72], [3.0, -2.0, 5.0, 4.0]])
    rows = [[t, *s.p, *s.v, *s.a] for t in np.arange(0.0, 3.0001, 0.05) for s in [src.state(t)]]
    pd.DataFrame(rows, columns=["t", "px", "py", "pz", "vx", "vy", "vz", "ax", "ay", "az"]).to_csv(path, index=False)


def test_a_run_folder_re_flies_bit_for_bit(tmp_path):
    csv = tmp_path / "elsewhere" / "flight.csv"
    csv.parent.mkdir()
    _csv_mission(csv)
    scen = tmp_path / "s.toml"
    scen.write_text(ar.load_scenario("scenarios/nominal_tilted.toml").to_toml().replace(
        "[mission]", f'[mission]\ntrajectory_csv = "{csv}"') .replace("waypoints = [[0.0, -3.04", "#waypoints = [[0.0, -3.04"))
    runner = CliRunner()
    first = tmp_path / "first"
    res = runner.invoke(app, ["run", str(scen), "--out", str(first), "--duration", "1.0", "--no-figures", "--no-bound"])
    assert res.exit_code == 0, res.output
    data = tomllib.loads((first / "scenario.toml").read_text())
    assert data["mission"]["trajectory_csv"] == "mission.csv" and "waypoints" not in data["mission"]
    assert (first / "mission.csv").read_bytes() == csv.read_bytes()
    csv.unlink()  # the original is gone: the run folder alone must suffice
    again = tmp_path / "again"
    res = runner.invoke(app, ["run", str(first / "scenario.toml"), "--out", str(again), "--no-figures", "--no-bound"])
    assert res.exit_code == 0, res.output
    a, b = pd.read_parquet(first / "timeseries.parquet"), pd.read_parquet(again / "timeseries.parquet")
    assert list(a.columns) == list(b.columns)
    for c in a.columns:
        if c not in TIMING:
            assert a[c].equals(b[c]), c
    assert (again / "scenario.toml").read_text() == (first / "scenario.toml").read_text()
