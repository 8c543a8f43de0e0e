from pathlib import Path

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
    out = res.output + (res.stderr if hasattr(res, "stderr") else "")
    assert "platform.mass_kg" in out and "controller.mu" in out and "[0, 1]" in out
    assert "Traceback" not in out


def test_info_prints_sanity_budget():
    res = runner.invoke(app, ["info", str(ROOT / "scenarios" / "nominal_tilted.toml")])
    assert res.exit_code == 0
    assert "0.0649" in res.output and "0.0129" in res.output and "61.56" in res.output
