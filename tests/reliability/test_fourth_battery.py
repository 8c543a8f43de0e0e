"""Cases of the fourth fault battery (issue 61) that each failed before their fix, as tests."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from aerorelay.cli import app

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()


def test_bench_of_a_network_with_a_spare_that_never_flies_times_the_others():
    """``aerorelay bench relay_shifts.toml`` was an IndexError: its spare waits on the ground, nothing timed."""
    r = runner.invoke(app, ["bench", str(ROOT / "scenarios" / "relay_shifts.toml"), "--duration", "1"])
    assert r.exit_code == 0, r.output
    assert "r1: step" in r.output and "spare never flew" in r.output
