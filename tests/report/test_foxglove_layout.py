"""The Foxglove layout names series the run's MCAP has (issue 48, item 6): generated per run folder
from its columns, for one relay and for a fleet (whose columns are ``r1.p_x``, ``sinr.r1.r2``, ...);
the documentation's layout for one relay too."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

import aerorelay as ar

ROOT = Path(__file__).resolve().parents[2]


def _paths(layout: dict) -> list[str]:
    return [p["value"].split(".", 1)[1] for panel in layout["configById"].values() for p in panel.get("paths", [])]


@pytest.mark.parametrize("preset", ["nominal_tilted", "chain_two_relays"])
def test_every_panel_names_a_series_of_its_run(tmp_path, preset):
    r = ar.simulate(ar.load_scenario(ROOT / "scenarios" / f"{preset}.toml", set={"sim.duration_s": 0.3}))
    r.save(tmp_path / "run")
    layout = json.loads((tmp_path / "run" / "foxglove_layout.json").read_text())
    columns = set(pd.read_parquet(tmp_path / "run" / "timeseries.parquet").columns)
    paths = _paths(layout)
    assert paths and set(paths) <= columns, set(paths) - columns
    for panel in ("Plot!capacity", "Plot!sinr", "Plot!motors"):
        assert layout["configById"][panel]["paths"], panel
    if preset == "chain_two_relays":
        assert {"sinr.inspector.r1", "sinr.r1.r2", "sinr.r2.bs", "r1.Omega_1"} <= set(paths)


def test_the_documented_layout_names_one_relays_series(tmp_path):
    r = ar.simulate(ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml", set={"sim.duration_s": 0.3}))
    doc = json.loads((ROOT / "docs" / "foxglove_layout.json").read_text())
    assert set(_paths(doc)) <= set(r.timeseries.columns)
