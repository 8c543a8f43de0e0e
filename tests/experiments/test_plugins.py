"""Users' planners from outside the package (issue 79, item 5): ``aerorelay --plugin MODULE`` imports a module that
registers them before the command, a campaign's workers (fresh processes) import it before their first run, and the
installed ``aerorelay.planners`` entry points load when a scenario names a planner not registered yet."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aerorelay.cli import app
from aerorelay.planning import plugins
from aerorelay.planning.base import PLANNERS

ROOT = Path(__file__).resolve().parents[2]
MODULE = '''
from aerorelay.planning.base import register_network_planner
from aerorelay.planning.fleet import held_reference


class Hold:
    def __init__(self, starts):
        self.starts = dict(starts)

    def update(self, inp):
        return {n: held_reference(p) for n, p in self.starts.items()}


@register_network_planner("{name}", references="position")
def _hold(ctx):
    return Hold(ctx.starts)
'''


def _module(folder: Path, name: str) -> Path:
    path = folder / f"{name}_planners.py"
    path.write_text(MODULE.replace("{name}", name))
    return path


def test_a_missing_or_broken_plugin_is_named_before_any_work(tmp_path):
    with pytest.raises(plugins.PluginError, match="--plugin no_such_planners: no module 'no_such_planners'"):
        plugins.resolve("no_such_planners", tmp_path)
    with pytest.raises(plugins.PluginError, match="--plugin gone.py: no such file"):
        plugins.resolve("gone.py", tmp_path)
    (tmp_path / "broken_planners.py").write_text("raise RuntimeError('half written')\n")
    with pytest.raises(plugins.PluginError, match="--plugin broken_planners: importing it raised RuntimeError: half written"):
        plugins.load([plugins.resolve("broken_planners", tmp_path)])
    res = CliRunner().invoke(app, ["--plugin", str(tmp_path / "gone.py"), "validate", str(ROOT / "scenarios/chain_two_relays.toml")])
    assert res.exit_code == 2 and "no such file" in res.output


def test_a_plugins_planner_flies_a_run_from_the_command_line(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _module(tmp_path, "cli_hold")
    try:
        res = CliRunner().invoke(app, ["--plugin", "cli_hold_planners", "run", str(ROOT / "scenarios/chain_two_relays.toml"),
                                       "--out", str(tmp_path / "run"), "--duration", "0.3", "--no-bound", "--no-figures",
                                       "--set", "controller.planner='cli_hold'"])
        assert res.exit_code == 0, res.output
        assert json.loads((tmp_path / "run" / "metrics.json").read_text())["planner_name"] == "cli_hold"
    finally:
        PLANNERS.pop("cli_hold", None)


def test_a_campaigns_workers_import_the_plugin(tmp_path, monkeypatch):
    """The worker is another process: without its import the run fails (the planner is not registered there)."""
    plugin = _module(tmp_path, "worker_hold")
    studies = tmp_path / "studies"
    studies.mkdir()
    (studies / "plugin_study.toml").write_text(
        f'name = "plugin_study"\ntitle = "a user\'s planner in a campaign"\nbase = "{ROOT / "scenarios/chain_two_relays.toml"}"\n'
        '[[runs]]\nid = "held"\nset = { "controller.planner" = "worker_hold", "sim.duration_s" = 0.3, "network.route" = false }\n')
    try:
        res = CliRunner().invoke(app, ["--plugin", str(plugin), "reproduce", "plugin_study", "--studies-dir", str(studies),
                                       "--out", str(tmp_path / "out"), "--workers", "1"])
        assert res.exit_code == 0, res.output
        manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
        assert [r["status"] for r in manifest.values()] == ["done"], manifest
    finally:
        PLANNERS.pop("worker_hold", None)


def test_installed_entry_points_load_when_a_planner_is_not_registered(monkeypatch):
    loaded = []

    class EntryPoint:
        name, value = "mine", "mine_pkg.planners"

        def load(self):
            loaded.append(self.name)

    monkeypatch.setattr(plugins, "entry_points", lambda group: [EntryPoint()] if group == "aerorelay.planners" else [])
    monkeypatch.setattr(plugins, "_ENTRY_POINTS_LOADED", False)
    from aerorelay.planning.base import planner_entry

    with pytest.raises(ValueError, match="no planner registered as 'not_there'"):
        planner_entry("not_there")
    assert loaded == ["mine"]
    with pytest.raises(ValueError):
        planner_entry("not_there")
    assert loaded == ["mine"]  # once per process
