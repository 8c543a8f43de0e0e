"""``--set`` as ``set=`` and ``--unset`` (issue 48, item 2): the updates apply to the file before it is
validated, so a file invalid alone can be made valid by them, on the command line as from Python; a
field can be removed (a preset's fixed jammer turned into a moving one)."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

import aerorelay as ar
from aerorelay.cli import app
from aerorelay.config import ScenarioError

ROOT = Path(__file__).resolve().parents[1]
NOMINAL = ROOT / "scenarios" / "nominal_tilted.toml"
runner = CliRunner()


def test_a_file_invalid_alone_is_rescued_by_set_on_the_command_line_as_from_python(tmp_path):
    f = tmp_path / "outside.toml"
    text = NOMINAL.read_text()
    assert "relay = [-6.95, 5.79, 1.72]" in text
    f.write_text(text.replace("relay = [-6.95, 5.79, 1.72]", "relay = [20.0, 0.0, 5.0]", 1))  # outside the workspace
    with pytest.raises(ScenarioError, match="nodes.relay"):
        ar.load_scenario(f)
    fixed = {"nodes.relay": [-6.95, 5.79, 1.72]}
    assert ar.load_scenario(f, set=fixed).nodes.relay == [-6.95, 5.79, 1.72]
    r = runner.invoke(app, ["validate", str(f), "--set", "nodes.relay=[-6.95, 5.79, 1.72]"])
    assert r.exit_code == 0, r.output


def test_unset_turns_a_fixed_jammer_into_a_moving_one():
    wps = [[0.0, 0.0, -5.0, 1.72], [20.0, 5.0, -5.0, 1.72]]
    with pytest.raises(ScenarioError):  # before: a position and waypoints both given
        ar.load_scenario(NOMINAL, set={"jammer.waypoints": wps})
    sc = ar.load_scenario(NOMINAL, set={"jammer.waypoints": wps}, unset=["jammer.position"])
    assert sc.jammer.waypoints == wps and sc.jammer.position == wps[0][1:]  # a moving jammer starts at its first waypoint
    r = runner.invoke(app, ["validate", str(NOMINAL), "--unset", "jammer.position", "--set", f"jammer.waypoints={wps}"])
    assert r.exit_code == 0, r.output


def test_a_key_that_walks_into_a_value_is_named():
    with pytest.raises(ScenarioError, match=r"seed\.x\.y: 'seed' is not a table"):
        ar.load_scenario(NOMINAL, set={"seed.x.y": 1})


def test_reproduce_lists_its_studies_without_a_campaign_folder(tmp_path):
    """Issue 48 (item 3): ``aerorelay reproduce --list`` names every study with its title and run count."""
    d = tmp_path / "studies"
    d.mkdir()
    (d / "tiny.toml").write_text(f'name = "tiny"\ntitle = "two short runs"\nbase = "{NOMINAL}"\n'
                                 '[[runs]]\nid = "a"\n[[runs]]\nid = "b"\nset = { seed = 1 }\n')
    r = runner.invoke(app, ["reproduce", "--list", "--studies-dir", str(d)])
    assert r.exit_code == 0 and "tiny" in r.output and "two short runs" in r.output and " 2 " in r.output
    r = runner.invoke(app, ["reproduce", "--studies-dir", str(d)])
    assert r.exit_code == 2 and "--out: a campaign folder is required" in r.output


def test_settings_that_would_do_nothing_are_named_and_derived_values_shown():
    """Issue 48 (item 6): a Doppler fading model without its K factor drew no fading, silently; a jammer
    power set from an INR printed the file's unused power_w in ``validate``."""
    with pytest.raises(ScenarioError, match=r"channel\.fading\.model: 'doppler' needs perturbations\.fading_k_db"):
        ar.load_scenario(NOMINAL, set={"channel.fading.model": "doppler"})
    assert ar.load_scenario(NOMINAL, set={"channel.fading.model": "doppler", "perturbations.fading_k_db": 6.0})
    chain = ROOT / "scenarios" / "chain_two_relays.toml"
    r = runner.invoke(app, ["validate", str(chain)])
    power = ar.build_scene(ar.load_scenario(chain)).jammers[0].power
    assert r.exit_code == 0 and f"# jammer.power_w: {power:.6g} W" in r.output and "derived from inr_db_at_relay_start = 10 dB" in r.output


def test_the_run_summary_shows_the_features_a_run_has(tmp_path):
    """Issue 48 (item 5): no rows of dashes for a bound or losses a run does not have; its wind's rows
    when it has one."""
    base = ["run", str(NOMINAL), "--duration", "0.3", "--no-figures", "--no-bound"]
    plain = runner.invoke(app, [*base, "--out", str(tmp_path / "a")])
    assert plain.exit_code == 0 and "c_min" in plain.output and "exit_status" in plain.output
    assert "capacity_efficiency" not in plain.output and "after_loss" not in plain.output and "wind_speed" not in plain.output
    windy = runner.invoke(app, [*base, "--out", str(tmp_path / "b"), "--set", "wind.mean_m_s=[3.0, 0.0, 0.0]"])
    assert windy.exit_code == 0 and "wind_speed_mean_m_s" in windy.output and "drag_accel_mean_m_s2" in windy.output


def test_unset_of_an_unknown_field_is_named_with_did_you_mean_and_of_an_absent_one_said(caplog):
    """Issue 61: ``--unset controller.nope`` removed nothing and said nothing (``--set`` says "did you mean")."""
    chain = ROOT / "scenarios" / "chain_two_relays.toml"
    with pytest.raises(ScenarioError, match=r"^--unset controller\.muu: not a field of the scenario; did you mean 'controller\.mu'\?"):
        ar.load_scenario(chain, unset=["controller.muu"])
    with pytest.raises(ScenarioError, match=r"^--unset controler\.mu: not a field of the scenario; did you mean 'controller'\?"):
        ar.load_scenario(chain, unset=["controler.mu"])
    ar.load_scenario(chain, unset=["controller.mu"])  # a field the file leaves out: nothing to remove, said
    assert any("--unset controller.mu: the file does not write it" in r.getMessage() for r in caplog.records)


def test_a_list_index_past_the_files_list_is_named_with_its_length():
    """Issue 61: ``--set relays.5.start`` said "'relays' is not a table"."""
    with pytest.raises(ScenarioError, match=r"relays\.5\.start: the file lists 2 \[\[relays\]\] \(numbered 0 to 1\)"):
        ar.load_scenario(ROOT / "scenarios" / "chain_two_relays.toml", set={"relays.5.start": [1.0, 2.0, 3.0]})
