"""Positions written at lat/lon (``<field>_wgs84``, issue 63 item 1): resolved once at load to the local frame at
``[geo] origin``, checked within 1 mm against an ECEF-to-ENU conversion written out in ``tests/geodesy.py`` (not the
program's transform); every kind of position (base stations, a relay's start, a jammer and its timed track, an
obstacle's corners); errors name the field before any work."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

import aerorelay as ar
from aerorelay.cli import app
from aerorelay.config import ScenarioError
from tests.geodesy import enu_by_hand
from tests.rt_marks import needs_rt

ORIGIN = [47.3977, 8.5456, 488.0]
runner = CliRunner()


def _near(lat_m: float, lon_m: float, up_m: float) -> list[float]:
    """A point about ``lat_m`` north, ``lon_m`` east and ``up_m`` above ORIGIN (deg, deg, m)."""
    return [ORIGIN[0] + lat_m / 111_200.0, ORIGIN[1] + lon_m / 75_100.0, ORIGIN[2] + up_m]


@needs_rt  # street_canyon.toml is traced: loading it needs the rt extra
def test_every_kind_of_position_resolves_within_a_millimetre():
    points = {"nodes.bs_wgs84": _near(0.5, -0.3, 0.01), "jammer.position_wgs84": _near(-5.0, -6.0, 1.7),
              "nodes.relay_wgs84": _near(5.5, -6.5, 1.9)}
    sc = ar.load_scenario("scenarios/nominal_tilted.toml", set={"geo.origin": ORIGIN, **points})
    for key, geo in points.items():
        table, field = key.removesuffix("_wgs84").split(".")
        local = getattr(getattr(sc, table), field)
        assert np.max(np.abs(np.asarray(local) - enu_by_hand(ORIGIN, *geo)[0])) < 1e-3, key
    assert {f for f, _ in sc.wgs84_resolved} == {"nodes.bs", "jammer.position", "nodes.relay"}
    track = [[0.0, *_near(-5.0, -6.0, 1.7)], [20.0, *_near(5.0, -6.0, 1.7)]]
    sc = ar.load_scenario("scenarios/moving_jammer.toml", set={"geo.origin": ORIGIN, "jammer.waypoints_wgs84": track})
    wp = np.asarray(sc.jammer.waypoints)
    assert list(wp[:, 0]) == [0.0, 20.0]  # the times kept
    expected = enu_by_hand(ORIGIN, [p[1] for p in track], [p[2] for p in track], [p[3] for p in track])
    assert np.max(np.abs(wp[:, 1:] - expected)) < 1e-3
    chain = ar.load_scenario("scenarios/chain_two_relays.toml",
                             set={"geo.origin": ORIGIN, "relays.0.start_wgs84": _near(2.0, 4.0, 3.0)})
    assert np.max(np.abs(np.asarray(chain.relay_list[0].start) - enu_by_hand(ORIGIN, *_near(2.0, 4.0, 3.0))[0])) < 1e-3
    corners = {"obstacles.0.min_m_wgs84": _near(9.6, -62.4, 0.01), "obstacles.0.max_m_wgs84": _near(20.0, -40.0, 15.0)}
    canyon = ar.load_scenario("scenarios/street_canyon.toml", set={"geo.origin": ORIGIN, **corners})
    box = canyon.obstacles[0]
    for local, geo in ((box.min_m, corners["obstacles.0.min_m_wgs84"]), (box.max_m, corners["obstacles.0.max_m_wgs84"])):
        assert np.max(np.abs(np.asarray(local) - enu_by_hand(ORIGIN, *geo)[0])) < 1e-3


def test_a_file_at_lat_lon_flies_as_the_same_file_in_metres(tmp_path):
    geo = _near(-5.79, -6.95, 1.72)
    a = ar.load_scenario("scenarios/nominal_tilted.toml",
                         set={"geo.origin": ORIGIN, "jammer.position_wgs84": geo, "sim.duration_s": 0.3})
    b = ar.load_scenario("scenarios/nominal_tilted.toml", set={"geo.origin": ORIGIN, "jammer.position": a.jammer.position,
                                                                "sim.duration_s": 0.3})
    ra, rb = ar.simulate(a), ar.simulate(b)
    assert ra.metrics["c_min"] == rb.metrics["c_min"]
    ra.save(tmp_path / "run", figures=False)
    text = (tmp_path / "run" / "scenario.toml").read_text()
    assert "_wgs84" not in text  # the run's file has the local positions it flew


@pytest.mark.parametrize(("sets", "needle"), [
    ({"jammer.position_wgs84": ORIGIN}, "jammer.position_wgs84: a WGS84 position needs [geo] origin"),
    ({"geo.origin": ORIGIN, "jammer.position_wgs84": [91.0, 8.5, 400.0]}, "jammer.position_wgs84: latitude 91"),
    ({"geo.origin": ORIGIN, "jammer.position_wgs84": [47.0, 181.0, 400.0]}, "longitude 181 in [-180, 180]"),
    ({"geo.origin": ORIGIN, "jammer.position_wgs84": [47.0, 8.0]}, "jammer.position_wgs84: [lat_deg, lon_deg, alt_m]"),
    ({"geo.origin": ORIGIN, "jammer.waypoints_wgs84": [[0.0, *ORIGIN], ORIGIN]}, "every point timed"),
])
def test_bad_wgs84_positions_are_named(sets, needle):
    with pytest.raises(ScenarioError) as exc:
        ar.load_scenario("scenarios/moving_jammer.toml", set=sets)
    assert needle in str(exc.value)


def test_both_forms_in_one_file_are_refused_and_validate_prints_the_resolved_position(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text(f"[geo]\norigin = {ORIGIN}\n[jammer]\nposition = [1.0, 2.0, 3.0]\nposition_wgs84 = {_near(1, 1, 1)}\n")
    with pytest.raises(ScenarioError, match="jammer.position_wgs84: give position .local, m. or position_wgs84"):
        ar.load_scenario(f)
    f.write_text(f"[geo]\norigin = {ORIGIN}\n[jammer]\nposition_wgs84 = {_near(-5.79, -6.95, 1.72)}\n")
    r = runner.invoke(app, ["validate", str(f)])
    assert r.exit_code == 0, r.output
    assert "# jammer.position_wgs84 resolves to jammer.position = [-6.9" in r.output
