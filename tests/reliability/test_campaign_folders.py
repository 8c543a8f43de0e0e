"""Campaigns that lose nothing and run folders read back with named errors (issue 45, item 3).
Before: two study runs with one id shared a folder (the second overwrote the first); ids ``a/b`` and
``a_b`` collided; an id ``..`` wrote outside the campaign's runs; a campaign of fleets crashed
building its report; ``export`` failed on every fleet run folder; ``report`` on a cut metrics.json or
a missing parquet and edited metric values broke ``compare`` / ``report`` with tracebacks."""

from __future__ import annotations

import json
import shutil
import tomllib
from pathlib import Path

import pytest
from typer.testing import CliRunner

import aerorelay as ar
from aerorelay.cli import app
from aerorelay.experiments.campaign import folder_name, run_dir
from aerorelay.experiments.study import RunSpec, StudyError, load_study

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()


def _study(tmp_path, runs: str, grid: str = "") -> Path:
    f = tmp_path / "s.toml"
    f.write_text(f'name = "s"\ntitle = "t"\nbase = "{ROOT / "scenarios" / "nominal_tilted.toml"}"\n{runs}\n{grid}')
    return f


def test_two_runs_with_one_id_are_refused(tmp_path):
    f = _study(tmp_path, '[[runs]]\nid = "a"\n[[runs]]\nid = "a"\nset = { seed = 3 }')
    with pytest.raises(StudyError, match="id 'a' appears 2 times"):
        load_study(f)


@pytest.mark.parametrize("bad", ["a/b", "..", ".", "a\\\\b"])
def test_ids_that_would_name_another_folder_are_refused(tmp_path, bad):
    f = _study(tmp_path, f'[[runs]]\nid = "{bad}"')
    with pytest.raises(StudyError, match="must not be '.' or '..' nor hold"):
        load_study(f)


def test_group_folders_never_collide_nor_escape(tmp_path):
    assert folder_name("a/b") == "a%2Fb" != folder_name("a_b") == "a_b"
    assert folder_name("..") == "%2E%2E" and folder_name("50%") == "50%25" != folder_name("50%25")
    assert folder_name("wind5[controller=paper,observer=on]") == "wind5[controller=paper,observer=on]"  # unchanged
    for group in ("..", "../x", "a/../../b", "x\n"):
        d = run_dir(tmp_path, RunSpec("s", group, 0, ""))
        assert d.resolve().is_relative_to((tmp_path / "runs" / "s").resolve()) and d.parent.parent == tmp_path / "runs" / "s"


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """A one-relay run folder and a fleet's, each 0.3 s."""
    root = tmp_path_factory.mktemp("folders")
    one = ar.simulate(ar.load_scenario("scenarios/nominal_tilted.toml", set={"sim.duration_s": 0.3}))
    one.save(root / "one")
    fleet = ar.simulate(ar.load_scenario("scenarios/chain_two_relays.toml", set={"sim.duration_s": 0.3}))
    fleet.save(root / "fleet")
    return root


def _copy(folders, name, to):
    d = folders.parent / f"{folders.name}_{to}"
    shutil.copytree(folders / name, d)
    return d


def test_export_and_report_work_on_a_fleets_folder(folders):
    (folders / "fleet" / "run.mcap").unlink()
    r = runner.invoke(app, ["export", str(folders / "fleet")])
    assert r.exit_code == 0, r.output
    assert (folders / "fleet" / "run.mcap").stat().st_size > 0
    r = runner.invoke(app, ["report", str(folders / "fleet")])
    assert r.exit_code == 0, r.output


@pytest.mark.parametrize("damage,named", [
    ("cut_metrics", "metrics.json: not readable JSON"),
    ("no_parquet", "timeseries.parquet: missing"),
    ("edited_metric", "metrics.json: c_min = 'abc' is not a number"),
    ("bad_scenario", "scenario.toml: not a valid scenario"),
])
def test_damaged_folders_are_named_by_report_export_and_compare(folders, damage, named):
    d = _copy(folders, "one", damage)
    m = d / "metrics.json"
    if damage == "cut_metrics":
        m.write_text(m.read_text()[:150])
    elif damage == "no_parquet":
        (d / "timeseries.parquet").unlink()
    elif damage == "edited_metric":
        m.write_text(json.dumps(json.loads(m.read_text()) | {"c_min": "abc"}))
    else:
        (d / "scenario.toml").write_text((d / "scenario.toml").read_text().replace("\nmu = ", "\nmu = 9.0 # ", 1))
        assert tomllib.loads((d / "scenario.toml").read_text())
    commands = [["report", str(d)], ["export", str(d)]]
    if damage in ("cut_metrics", "edited_metric"):
        commands.append(["compare", str(folders / "one"), str(d)])
    for cmd in commands:
        r = runner.invoke(app, cmd)
        assert r.exit_code == 2 and named in " ".join(r.output.split()), (cmd, r.output)
        assert "Traceback" not in r.output


def test_a_fleet_campaign_writes_its_report(tmp_path):
    studies = tmp_path / "studies"
    studies.mkdir()
    (studies / "chain.toml").write_text(f'name = "chain"\ntitle = "a chain"\nbase = "{ROOT / "scenarios" / "chain_two_relays.toml"}"\n'
                                        '[[runs]]\nid = "eq"\nset = { "sim.duration_s" = 0.3 }\n')
    rep = ar.api.reproduce(None, out=tmp_path / "out", studies_dir=studies, workers=1)
    assert rep.campaign.ran == 1 and rep.summary["campaign"]["runs_finished"] == 1
    page = (tmp_path / "out" / "report.html").read_text()
    assert "r1: eq" in page and "r2: eq" in page  # the 3D view draws each relay of the chain
