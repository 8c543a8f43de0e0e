"""`aerorelay report`: a report from whatever runs are finished, partial studies marked; a custom
study gets its own title and no paper claims table."""

from pathlib import Path

from typer.testing import CliRunner

from aerorelay.cli import app

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
    res = runner.invoke(app, ["report", str(out), "--studies-dir", str(studies)])
    assert res.exit_code == 0 and "1 of 2 runs finished" in res.output, res.output
    html = (out / "report.html").read_text()
    assert "Partial report: 1 of 2 runs finished" in html and "1 run(s) without results" in html


def test_report_on_a_folder_that_is_no_campaign(tmp_path):
    res = CliRunner().invoke(app, ["report", str(tmp_path)])
    assert res.exit_code == 2 and "no campaign here" in res.output
