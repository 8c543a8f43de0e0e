"""`aerorelay report`: a report from whatever runs are finished, partial studies marked; a custom
study gets its own title and no paper claims table."""

from pathlib import Path

from typer.testing import CliRunner

from aerorelay.assembly import parse_scenario
from aerorelay.cli import app
from aerorelay.experiments.study import RunSpec
from aerorelay.report.html import _headers, capacity_unit

ROOT = Path(__file__).resolve().parents[2]
CUSTOM = f"""
name = "mine"
title = "my relay sweep"
base = "{ROOT / 'scenarios' / 'nominal_tilted.toml'}"
[[runs]]
id = "a"
set = {{ "sim.duration_s" = 0.3 }}
[[runs]]
id = "b"
set = {{ "sim.duration_s" = 0.3, "controller.mu" = 0.3 }}
"""


def test_report_of_a_partial_custom_campaign(tmp_path):
    studies = tmp_path / "studies"
    studies.mkdir()
    (studies / "mine.toml").write_text(CUSTOM)
    out = tmp_path / "camp"
    runner = CliRunner()
    res = runner.invoke(app, ["reproduce", "--out", str(out), "--studies-dir", str(studies), "--workers", "1"])
    assert res.exit_code == 0, res.output
    html = (out / "report.html").read_text()
    assert "<h1>aerorelay: my relay sweep</h1>" in html and "claims on our numbers" not in html
    assert "Partial report" not in html
    (out / "runs" / "mine" / "b" / "seed0" / "timeseries.parquet").write_bytes(b"")  # a run that no longer checks out
    res = runner.invoke(app, ["report", str(out)])  # the campaign folder alone: it knows its studies folder
    assert res.exit_code == 0 and "1 of 2 runs finished" in res.output, res.output
    html = (out / "report.html").read_text()
    assert "Partial report: 1 of 2 runs finished" in html and "1 run(s) without results" in html


def test_report_on_a_folder_that_is_no_campaign(tmp_path):
    res = CliRunner().invoke(app, ["report", str(tmp_path)])
    assert res.exit_code == 2 and "no campaign here" in res.output


def test_capacity_units_follow_the_runs_link_budget():
    """Capacities are bit/s/Hz in the paper's normalized units and bit/s in physical ones; a study table
    that mixes both names both."""
    norm = parse_scenario({})
    phys = norm.with_updates({"channel.units": "physical"})
    assert (norm.channel.capacity_unit, phys.channel.capacity_unit) == ("bit/s/Hz", "bit/s")
    spec = lambda sc: RunSpec("s", "g", 0, sc.to_toml(), False)  # noqa: E731
    assert capacity_unit([spec(phys), spec(phys)]) == "bit/s"
    assert capacity_unit([spec(norm), spec(phys)]) == "bit/s/Hz; physical-unit runs bit/s"
    assert _headers(["c_min", "outage_fraction"], "bit/s") == ["C_min (bit/s)", "outage fraction"]


def test_report_of_one_run_folder(tmp_path):
    """`aerorelay report RUN_DIR`: one self-contained page with the run's metrics in their units, its
    safety verdict and its figures, drawn from the folder's files (also for a run without figures)."""
    runner = CliRunner()
    run = tmp_path / "r"
    res = runner.invoke(app, ["run", str(ROOT / "scenarios" / "nominal_tilted.toml"), "--out", str(run), "--duration", "0.5",
                              "--no-bound", "--no-figures"])
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["report", str(run)])
    assert res.exit_code == 0, res.output
    page = (run / "report.html").read_text()
    assert "c_min" in page and "bit/s/Hz" in page and "safe:" in page and page.count("data:image/png;base64,") == 5
    assert "nominal_tilted" in page and "<pre>" in page


SWEEP = f"""
name = "sweep"
title = "my mu sweep"
base = "{ROOT / 'scenarios' / 'nominal_tilted.toml'}"
[[runs]]
id = "base"
set = {{ "sim.duration_s" = 0.3 }}
[grid]
"controller.mu" = [0.1, 0.2, 0.3]
"""


def test_a_custom_sweep_is_plotted_against_c_min_and_mean_c(tmp_path):
    studies = tmp_path / "studies"
    studies.mkdir()
    (studies / "sweep.toml").write_text(SWEEP)
    out = tmp_path / "camp"
    res = CliRunner().invoke(app, ["reproduce", "--out", str(out), "--studies-dir", str(studies), "--workers", "1"])
    assert res.exit_code == 0, res.output
    page = (out / "report.html").read_text()
    start = page.index("Swept: <code>controller.mu</code>")
    assert "data:image/png;base64," in page[start:start + 400]
