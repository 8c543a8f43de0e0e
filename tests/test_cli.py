from pathlib import Path

import pytest
from typer.testing import CliRunner

from aerorelay.cli import app

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()


def test_validate_prints_resolved_scenario():
    res = runner.invoke(app, ["validate", str(ROOT / "scenarios" / "nominal_tilted.toml")])
    assert res.exit_code == 0
    assert "valid" in res.output and "[controller.weights]" in res.output


def test_validate_bad_input_exit_2_without_traceback(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[platform]\nmass_kg = -2.0\n[controller]\nmu = 3\n")
    res = runner.invoke(app, ["validate", str(bad)])
    assert res.exit_code == 2
    out = res.output  # click 8.1 mixes stderr into output
    assert "platform.mass_kg" in out and "controller.mu" in out and "[0, 1]" in out
    assert "Traceback" not in out


def test_info_prints_sanity_budget():
    res = runner.invoke(app, ["info", str(ROOT / "scenarios" / "nominal_tilted.toml")])
    assert res.exit_code == 0
    assert "0.0649" in res.output and "0.0129" in res.output and "61.56" in res.output


def test_info_on_a_fleet_with_a_spare_and_two_base_stations():
    """The spare is listed (its start is no node of the network yet), each base station's hops are in the budget."""
    res = runner.invoke(app, ["info", str(ROOT / "scenarios" / "relay_shifts.toml")])
    assert res.exit_code == 0, res.output
    assert "spare" in res.output and "depot, substation" in res.output and "r2 -> substation: SINR" in res.output


def test_scenario_that_is_not_utf8_is_a_named_error(tmp_path):
    bad = tmp_path / "latin1.toml"
    bad.write_bytes('name = "Kraftwerk Süd"\n'.encode("latin-1"))
    res = runner.invoke(app, ["validate", str(bad)])
    assert res.exit_code == 2 and "not UTF-8" in res.output and "Traceback" not in res.output


def test_infinite_duration_is_a_named_error(tmp_path):
    bad = tmp_path / "inf.toml"
    bad.write_text("[sim]\nduration_s = inf\n")
    res = runner.invoke(app, ["run", str(bad), "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "sim.duration_s" in res.output and "finite" in res.output
    assert not (tmp_path / "o").exists()


def test_any_rotor_count_end_to_end(tmp_path):
    """quad_x (4 rotors, custom layout) and octo_tilted (8): the log, parquet, metrics and figures follow the vehicle."""
    import json

    import pandas as pd

    from aerorelay.assembly import load_scenario
    from aerorelay.assembly.parts import build_scene
    from aerorelay.sim.log_schema import log_columns

    for preset, n in (("quad_x", 4), ("octo_tilted", 8)):
        out = tmp_path / preset
        res = runner.invoke(app, ["run", str(ROOT / "scenarios" / f"{preset}.toml"), "--out", str(out), "--duration", "1.0"])
        assert res.exit_code == 0, res.output
        df = pd.read_parquet(out / "timeseries.parquet")
        columns = log_columns({"relay": n}, ["source"], build_scene(load_scenario(ROOT / "scenarios" / f"{preset}.toml")))
        assert list(df.columns) == columns  # the relay's, the source's, the links', the jammers' true positions
        assert f"relay.Omega_{n}" in df and f"relay.Omega_{n + 1}" not in df
        assert df["source.p_x"].iloc[0] == -3.04  # MRAV-2's start, not a motor speed shifted into it
        m = json.loads((out / "metrics.json").read_text())
        assert m["infeasible_fraction"] == 0 and m["fallback_fraction"] == 0
        assert (out / "constraints_relay.png").stat().st_size > 0


def test_bound_command_and_run_report_the_efficiency(tmp_path):
    import json

    import pandas as pd

    scen = tmp_path / "s.toml"
    scen.write_text('[sim]\nduration_s = 1.5\n[bound]\ngrid_m = 1.0\n')
    res = runner.invoke(app, ["bound", str(scen), "--out", str(tmp_path / "b")])
    assert res.exit_code == 0, res.output
    summary = json.loads((tmp_path / "b" / "bound.json").read_text())
    assert set(summary) >= {"static", "path_mean", "path_maxmin", "resolution", "assumptions"}
    assert summary["resolution"]["grid_m"] == 1.0 and summary["resolution"]["times"] == 4
    assert (tmp_path / "b" / "bound.png").stat().st_size > 0
    res = runner.invoke(app, ["run", str(scen), "--out", str(tmp_path / "r"), "--no-figures"])
    assert res.exit_code == 0, res.output
    m = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert m["capacity_efficiency_mean"] == pytest.approx(m["c_mean"] / summary["path_mean"]["mean"])
    assert m["capacity_efficiency_min"] == pytest.approx(m["c_min"] / summary["path_maxmin"]["min"])
    assert len(pd.read_parquet(tmp_path / "r" / "bound.parquet")) == 4


def test_set_overrides_are_validated_and_recorded(tmp_path):
    import tomllib

    res = runner.invoke(app, ["validate", str(ROOT / "scenarios" / "nominal_tilted.toml"), "--set", "controller.mu=0.3",
                              "--set", "nodes.relay=[-6.0, 5.0, 2.0]"])
    assert res.exit_code == 0, res.output
    body = res.output.split("\n", 1)[1]
    data = tomllib.loads(body)
    assert data["controller"]["mu"] == 0.3 and data["nodes"]["relay"] == [-6.0, 5.0, 2.0]
    assert "relay = [-6.0, 5.0, 2.0]" in body  # arrays on one line
    res = runner.invoke(app, ["validate", str(ROOT / "scenarios" / "nominal_tilted.toml"), "--set", "controller.mu=3"])
    assert res.exit_code == 2 and "controller.mu" in res.output and "[0, 1]" in res.output
    res = runner.invoke(app, ["run", str(ROOT / "scenarios" / "nominal_tilted.toml"), "--out", str(tmp_path / "r"),
                              "--no-bound", "--no-figures", "--set", "sim.duration_s=0.3", "--set", "controller.mu=0.25"])
    assert res.exit_code == 0, res.output
    recorded = tomllib.loads((tmp_path / "r" / "scenario.toml").read_text())
    assert recorded["controller"]["mu"] == 0.25 and recorded["sim"]["duration_s"] == 0.3


def test_reproduce_help_names_every_study_with_its_title():
    """Issue 48 (item 3): ``aerorelay reproduce --help`` lists the studies there are (``--list`` also counts runs)."""
    import tomllib

    res = runner.invoke(app, ["reproduce", "--help"], terminal_width=200)
    assert res.exit_code == 0
    text = " ".join(res.output.split())
    for f in sorted((ROOT / "experiments").glob("*.toml")):
        data = tomllib.loads(f.read_text())
        assert f"{data['name']}: {' '.join(data['title'].split())[:40]}" in text, data["name"]


def handover_one_relay() -> str:
    """The handover test's crossing (one relay, routes to "any" of two base stations) with no planner named."""
    from tests.sim.test_handover import CROSSING
    named = '[controller]\nplanner = "capacity"\n'
    assert named in CROSSING
    return CROSSING.replace(named, "[controller]\n")


def test_command_line_options_apply_before_validation(tmp_path):
    """A file valid only with the planner ``--planner`` names flies (the options are applied before the file is
    validated, as ``--set`` is): one relay that may hand over between two base stations is refused for the paper's
    generator (the default) and flies with ``--planner capacity``; ``--duration`` too is what is validated."""
    f = tmp_path / "handover.toml"
    f.write_text(handover_one_relay())
    refused = runner.invoke(app, ["validate", str(f)])
    assert refused.exit_code == 2 and "controller.planner" in refused.output
    flown = runner.invoke(app, ["run", str(f), "--planner", "capacity", "--duration", "0.3", "--no-bound",
                                "--out", str(tmp_path / "run")])
    assert flown.exit_code == 0, flown.output
    import tomllib
    written = tomllib.loads((tmp_path / "run" / "scenario.toml").read_text())
    assert written["controller"]["planner"] == "capacity" and written["sim"]["duration_s"] == 0.3
    bad = runner.invoke(app, ["run", str(f), "--planner", "capacity", "--duration", "-1", "--out", str(tmp_path / "bad")])
    assert bad.exit_code == 2 and "sim.duration_s" in bad.output and not (tmp_path / "bad").exists()


def test_info_describes_every_relay_with_its_own_platform_limits_and_antenna(tmp_path):
    """``aerorelay info`` on a chain of a quadrotor (its own speed limit and antenna) and the shared hexarotor: each
    relay's rotors, hover, speed limit and antenna, by name (before: the first relay's platform only)."""
    f = tmp_path / "mixed.toml"
    f.write_text((ROOT / "scenarios" / "chain_two_relays.toml").read_text())
    res = runner.invoke(app, ["info", str(f), "--set", "relays.0.platform=quad_x", "--set",
                              "relays.0.controller.capacity.speed_m_s=0.4", "--set", "relays.0.antenna.pattern=isotropic"])
    assert res.exit_code == 0, res.output
    import aerorelay as ar
    sc = ar.load_scenario(f)
    first, second = (r.name for r in sc.relay_list)
    out = " ".join(res.output.split())
    assert f"{first}: rotors / max axis tilt │ 4 (custom layout)" in out and f"{second}: rotors / max axis tilt │ 6" in out
    assert f"{first}: speed limit / governor (m/s) │ 0.4" in out and f"{second}: speed limit / governor (m/s) │ 1 " in out
    assert f"{first}: antenna │ isotropic (its own" in out and f"{second}: antenna │ dipole (shared)" in out
