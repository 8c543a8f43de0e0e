"""A jammer on a track from a file (issue 48, item 1): a CSV (a truck along a road), a GPX track and a
QGroundControl .plan in the scenario's local frame (``[geo] origin``); the jammer flies the file's
positions (checked against the file's own rows and, for the geographic ones, the closed-form ENU of
tests/models/test_geo.py); its file is copied into the run folder, which flies the same run again; a bad
file or a track beside waypoints is a named error before anything flies."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly.parts import build_scene
from aerorelay.config import ScenarioError

from .models.test_geo import HOME, _east, _enu, _gpx, _item, _north, _plan

ROOT = Path(__file__).resolve().parents[1]
NOMINAL = ROOT / "scenarios" / "nominal_tilted.toml"


def _truck(tmp_path) -> Path:
    f = tmp_path / "truck.csv"
    t = np.arange(0.0, 10.01, 0.5)
    rows = np.column_stack([t, -8.0 + 1.2 * t, -6.0 + 0.1 * t, np.full_like(t, 1.5)])
    f.write_text("t,px,py,pz\n" + "\n".join(",".join(f"{v:.6f}" for v in r) for r in rows))
    return f


def test_a_jammer_on_a_csv_track_flies_its_rows_and_its_folder_flies_again(tmp_path):
    f = _truck(tmp_path)
    sc = ar.load_scenario(NOMINAL, set={"sim.duration_s": 0.6, "jammer.trajectory_csv": str(f)}, unset=["jammer.position"])
    jam = build_scene(sc).jammers[0]
    for t in (0.0, 2.5, 7.0):
        np.testing.assert_allclose(jam.position_at(t), [-8.0 + 1.2 * t, -6.0 + 0.1 * t, 1.5], atol=1e-6)
    r = ar.simulate(sc)
    np.testing.assert_allclose(r.timeseries["jam_jammer_x"].iloc[-1], -8.0 + 1.2 * r.timeseries["t"].iloc[-1], atol=1e-6)
    run = r.save(tmp_path / "run", figures=False)
    assert (run / "jammer_jammer.csv").read_text() == f.read_text()
    assert 'trajectory_csv = "jammer_jammer.csv"' in (run / "scenario.toml").read_text()
    again = ar.simulate(ar.load_scenario(run / "scenario.toml")).timeseries
    for c in r.timeseries.columns:
        if not c.endswith("_ms"):
            assert again[c].equals(r.timeseries[c]), c


def test_a_jammer_on_a_gpx_track_and_on_a_plan_in_the_local_frame_at_the_geo_origin(tmp_path):
    pts = [(k * 2.0, HOME[0] + _north(-6.0 + 1.0 * k), HOME[1] + _east(-7.0), HOME[2] + 1.5) for k in range(6)]
    gpx = _gpx(tmp_path, pts)
    sc = ar.load_scenario(NOMINAL, set={"jammer.trajectory_gpx": str(gpx), "geo.origin": list(HOME)}, unset=["jammer.position"])
    jam = build_scene(sc).jammers[0]
    for t, lat, lon, ele in pts:
        np.testing.assert_allclose(jam.position_at(t), _enu(HOME, lat, lon, ele), atol=1e-3)
    items = [_item(22, HOME[0] + _north(-5.0), HOME[1] + _east(-6.0), 2.0),
             _item(16, HOME[0] + _north(-5.0), HOME[1] + _east(4.0), 2.0)]
    plan = _plan(tmp_path, items, hover_speed=2.0)
    sc = ar.load_scenario(NOMINAL, set={"jammer.trajectory_plan": str(plan), "geo.origin": list(HOME)}, unset=["jammer.position"])
    jam = build_scene(sc).jammers[0]
    a, b = _enu(HOME, HOME[0] + _north(-5.0), HOME[1] + _east(-6.0), HOME[2] + 2.0), \
        _enu(HOME, HOME[0] + _north(-5.0), HOME[1] + _east(4.0), HOME[2] + 2.0)
    np.testing.assert_allclose(jam.position_at(0.0), a, atol=1e-3)
    np.testing.assert_allclose(jam.position_at(np.linalg.norm(b - a) / 2.0 + 1.0), b, atol=1e-3)  # 10 m at 2 m/s, then held


@pytest.mark.parametrize(("updates", "named"), [
    ({"jammer.trajectory_csv": "nowhere.csv"}, r"jammer.*trajectory_csv: no such file"),
    ({"jammer.waypoints": [[0.0, 1.0, 1.0, 1.0], [5.0, 2.0, 1.0, 1.0]]}, r"trajectory_csv is the jammer's path: not with waypoints"),
    ({"jammer.position": [0.0, 0.0, 1.0]}, r"position \[0.0, 0.0, 1.0\] is not trajectory_csv's start"),
])
def test_a_bad_jammer_track_is_named_before_anything_flies(tmp_path, updates, named):
    f = _truck(tmp_path)
    data = {"jammer.trajectory_csv": str(f), **updates}
    unset = [] if "jammer.position" in updates else ["jammer.position"]
    with pytest.raises(ScenarioError, match=named):
        ar.load_scenario(NOMINAL, set=data, unset=unset)
    bad = tmp_path / "bad.csv"
    bad.write_text("t,px,py,pz\n0,1,2,3\n1,nan,2,3\n")
    with pytest.raises(ScenarioError, match=r"jammer.*trajectory_csv"):
        ar.load_scenario(NOMINAL, set={"jammer.trajectory_csv": str(bad)}, unset=["jammer.position"])
