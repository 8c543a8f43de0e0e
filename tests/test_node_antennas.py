"""Antennas per node in the scenario file (issue 46): ``[[relays]] antenna = {...}`` and
``[[sources]] antenna = {...}`` give a vehicle its own pattern about its body z, ``[antenna]`` stays
the default; the scene carries it, the logged SINR is the link equation with that pattern, the run
folder's scenario.toml keeps it (the folder flies again as it flew), and the paper's comms-aware NMPC
refuses a pattern its misalignment terms do not fit."""

from __future__ import annotations

import copy
import math
import tomllib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import aerorelay as ar
from aerorelay.assembly import parse_scenario
from aerorelay.config import ScenarioError
from aerorelay.models.antenna import CosinePattern, DipolePattern, FlippedPattern, SinPowerPattern

from .sim.test_fleet import CHAIN, _axis, _dipole

PATCH = {"pattern": "cosine", "g_bar": 4.0, "exponent": 2.0, "back_lobe": 0.05}


def _chain(**relay_antennas):
    d = copy.deepcopy(CHAIN)
    d["sim"] = {"duration_s": 0.6}
    d["network"]["planner"] = "capacity"
    for r in d["relays"]:
        if r["name"] in relay_antennas:
            r["antenna"] = relay_antennas[r["name"]]
    return d


def _patch_link_sinr(row, along: float) -> float:
    """r1 -> r2's SINR from the logged poses, written here: Gamma = G_r1 G_r2 / d^2 / (1 + P_J G_J / d_J^2), r1's
    patch G = 4 max(max(cos psi, 0)^2, 0.05) with psi off ``along`` times its body z (+1 up, -1 down), r2's dipole,
    the jammer isotropic at P_J = 4 W."""
    p1, p2 = (np.array([row[f"{n}.p_x"], row[f"{n}.p_y"], row[f"{n}.p_z"]]) for n in ("r1", "r2"))
    b1, b2 = (_axis(row[f"{n}.phi"], row[f"{n}.theta"], row[f"{n}.psi"]) for n in ("r1", "r2"))
    d = p2 - p1
    n = float(np.linalg.norm(d))
    g1 = 4.0 * max(max(float(d @ (along * b1)) / n, 0.0) ** 2, 0.05)
    g2 = _dipole(float(-d @ b2) / n)
    pj = np.array([row["jam_jammer_x"], row["jam_jammer_y"], row["jam_jammer_z"]])
    dj = p2 - pj
    nj = float(np.linalg.norm(dj))
    interference = 4.0 * _dipole(float(-dj @ b2) / nj) / nj**2
    return g1 * g2 / n**2 / (1.0 + interference)


def test_each_vehicle_gets_its_own_pattern():
    d = _chain(r1=PATCH)
    d["sources"][0]["antenna"] = {"pattern": "sin_power", "exponent": 4.0, "g_bar": 2.0}
    scene = ar.build_scene(parse_scenario(d))
    assert scene.node("r1").antenna.pattern == CosinePattern(4.0, 2.0, 0.05)
    assert isinstance(scene.node("r2").antenna.pattern, DipolePattern)  # [antenna]'s
    assert scene.node("inspector").antenna.pattern == SinPowerPattern(4.0, 2.0)


def test_the_logged_sinr_is_the_link_equation_with_the_patch(tmp_path):
    """r1 -> r2 with r1's patch: Gamma = G_r1 G_r2 / d^2 / (1 + P_J G_J / d_J^2), the patch's
    G = 4 max(max(cos psi, 0)^2, 0.05) off r1's body z (written here, not from models.antenna)."""
    sc = parse_scenario(_chain(r1=PATCH))
    r = ar.simulate(sc)
    row = r.timeseries.iloc[len(r.timeseries) // 2]
    assert row["sinr.r1.r2"] == pytest.approx(_patch_link_sinr(row, +1.0), rel=1e-9)
    # the run folder's scenario.toml keeps the antenna: flown again from it, the same run
    r.save(tmp_path / "run")
    again = ar.load_scenario(tmp_path / "run" / "scenario.toml")
    assert tomllib.loads((tmp_path / "run" / "scenario.toml").read_text())["relays"][0]["antenna"]["pattern"] == "cosine"
    assert np.array_equal(ar.simulate(again).timeseries["sinr.r1.r2"].to_numpy(), r.timeseries["sinr.r1.r2"].to_numpy())


def test_the_comms_aware_nmpc_refuses_an_antenna_it_does_not_fit():
    d = _chain(r1=PATCH)
    d["network"]["planner"] = "trajectory_generator"
    with pytest.raises(ScenarioError, match=r"relays\[0\]\.antenna: a cosine antenna on relay 'r1' with the paper's comms-aware NMPC"):
        ar.api.updated(parse_scenario(d), {"seed": 1})  # the checks a loaded scenario gets
    d["controller"] |= {"variant": "unconstrained"}
    assert ar.api.updated(parse_scenario(d), {"seed": 1}).relay_list[0].antenna.pattern == "cosine"
    assert math.isfinite(parse_scenario(_chain(r1={"pattern": "sin_power", "exponent": 3.0})).relay_list[0].antenna.exponent)


def test_a_run_with_parts_passed_from_python_names_them_and_its_folder_does_not_fly_another_run(tmp_path):
    """Issue 46: a planner passed to ar.simulate is named in metrics.json and in the run folder's
    scenario.toml (``injected``); that file alone is refused by name (aerorelay run exits 2), with the
    part given again it flies."""
    from typer.testing import CliRunner

    from aerorelay.cli import app

    class Hold:
        def __init__(self):
            self.p = None

        def update(self, inp):
            self.p = inp.p1.copy() if self.p is None else self.p
            return ar.Reference(p_opt=self.p, p_ref=self.p.copy(), v_ref=np.zeros(3), a_ref=np.zeros(3))
    sc = ar.load_scenario("scenarios/nominal_tilted.toml", set={"sim.duration_s": 0.3, "controller.variant": "unconstrained"})
    r = ar.simulate(sc, planner=Hold())
    assert r.metrics["injected"] == ["planner: Hold"]
    r.save(tmp_path / "run")
    again = ar.load_scenario(tmp_path / "run" / "scenario.toml")
    assert again.injected == ["planner: Hold"]
    with pytest.raises(ScenarioError, match=r"injected: this scenario was flown with parts passed from Python \(planner: Hold\)"):
        ar.simulate(again)
    res = CliRunner().invoke(app, ["run", str(tmp_path / "run" / "scenario.toml"), "--out", str(tmp_path / "x"), "--no-bound"])
    assert res.exit_code == 2 and "injected: this scenario was flown with parts passed from Python" in " ".join(res.output.split())
    assert ar.simulate(again, planner=Hold()).metrics["steps"] == r.metrics["steps"]
    assert "injected" not in sc.to_toml()  # a scenario flown from its file alone says nothing of it


def test_jammers_passed_from_python_are_written_as_tables_and_the_folder_flies_them_again(tmp_path):
    """Issue 46 (item 3): jammers a table can say (static or on a circle or waypoints, always-on or on-off,
    isotropic or cosine) passed to ``ar.simulate`` become the run folder's ``[[jammers]]``: its
    ``scenario.toml`` flies the same run bit for bit, and nothing is named as injected."""
    import numpy as np

    from aerorelay.assembly.parts import build_jammer, jammer_table
    from aerorelay.config import JammerConfig
    from aerorelay.models.antenna import CosinePattern
    from aerorelay.models.jammer import Jammer, PeriodicOnOff
    from aerorelay.models.mission import CirclePath, LinearPath, RepeatingPath

    jams = [Jammer(position=np.array([-3.0, -2.0, 1.5]), power=2.0, schedule=PeriodicOnOff(0.2, 0.1), name="pulsed",
                   path=CirclePath([-5.0, -2.0, 1.5], 2.0, 7.0, clockwise=True)),
            Jammer(position=np.array([3.0, -6.0, 2.0]), power=0.5, pattern=CosinePattern(4.0, 2.0, 0.05), point_at="relay",
                   name="panel", path=RepeatingPath(LinearPath([[0.0, 3.0, -6.0, 2.0], [1.0, 4.0, -6.0, 2.0],
                                                               [2.0, 3.0, -6.0, 2.0]])))]
    for j in jams:  # a table builds the jammer again
        again = build_jammer(JammerConfig(**jammer_table(j)))
        for t in (0.0, 0.37, 1.9, 5.3):
            np.testing.assert_allclose(again.position_at(t), j.position_at(t), rtol=0, atol=1e-12)
            assert again.power_at(t) == j.power_at(t)
    sc = ar.load_scenario("scenarios/nominal_tilted.toml", set={"sim.duration_s": 0.6})
    r = ar.simulate(sc, jammers=jams)
    assert "injected" not in r.metrics and [j.name for j in r.scenario.jammer_configs] == ["pulsed", "panel"]
    run = r.save(tmp_path / "run", figures=False)
    flown = ar.simulate(ar.load_scenario(run / "scenario.toml")).timeseries
    for c in r.timeseries.columns:
        if not c.endswith("_ms"):
            assert flown[c].equals(r.timeseries[c]), c


def test_a_jammer_a_table_cannot_say_is_named_as_injected():
    import numpy as np

    from aerorelay.assembly.parts import jammer_table
    from aerorelay.models.jammer import Jammer, PeriodicOnOff

    odd = Jammer(position=np.array([-5.0, -4.0, 1.5]), power=1.0, schedule=PeriodicOnOff(1.0, 1.0, phase_s=0.3))
    assert jammer_table(odd) is None
    r = ar.simulate(ar.load_scenario("scenarios/nominal_tilted.toml", set={"sim.duration_s": 0.15}), jammers=[odd])
    assert r.metrics["injected"] == ["jammers: jammer"]


@settings(max_examples=60, deadline=None)
@given(pattern=st.sampled_from([CosinePattern(4.0, 2.0, 0.05), CosinePattern(2.0, 5.0, 0.0), SinPowerPattern(3.0, 2.0),
                                DipolePattern(1.5)]),
       a=st.floats(-1.0, 1.0), b=st.floats(-1.0, 1.0))
def test_an_antenna_pointing_down_is_the_upward_one_mirrored(pattern, a, b):
    """Reversing an antenna's axis reverses the cosine of every direction to it: G_down(c) = G_up(-c); its gain bounds
    over [lo, hi] hold every sampled gain and are reached (the built-in patterns' extremes are at the ends or at 0)."""
    down = FlippedPattern(pattern)
    lo, hi = min(a, b), max(a, b)
    c = np.linspace(lo, hi, 201)
    g = down.gain_from_cos(c)
    assert np.array_equal(g, pattern.gain_from_cos(-c))
    least, most = down.gain_bounds(lo, hi)
    assert least <= g.min() + 1e-12 and most >= g.max() - 1e-12
    inside = np.append(c, 0.0) if lo <= 0.0 <= hi else c
    assert least == pytest.approx(pattern.gain_from_cos(-inside).min(), abs=1e-12)
    assert most == pytest.approx(pattern.gain_from_cos(-inside).max(), abs=1e-12)


def test_a_patch_pointing_down_is_flown_with_the_link_equation_about_body_minus_z():
    """``antenna.axis = [0, 0, -1]`` (a patch under the vehicle): r1 -> r2's logged SINR is the link equation with
    G = 4 max(max(cos psi, 0)^2, 0.05), psi off r1's body -z (written here); an axis off body z is refused by name."""
    sc = parse_scenario(_chain(r1=PATCH | {"axis": [0.0, 0.0, -2.0]}))
    assert sc.relay_list[0].antenna.axis == [0.0, 0.0, -1.0]
    r = ar.simulate(sc)
    row = r.timeseries.iloc[len(r.timeseries) // 2]
    assert row["sinr.r1.r2"] == pytest.approx(_patch_link_sinr(row, -1.0), rel=1e-9)
    up = ar.simulate(parse_scenario(_chain(r1=PATCH))).timeseries.iloc[len(r.timeseries) // 2]
    assert row["sinr.r1.r2"] != pytest.approx(up["sinr.r1.r2"], rel=1e-3)  # the axis is not ignored
    with pytest.raises(ScenarioError, match=r"relays\.0\.antenna\.axis: must be along the body z axis"):
        parse_scenario(_chain(r1=PATCH | {"axis": [0.0, 0.3, -1.0]}))
