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


def test_one_file_that_is_no_study_does_not_hide_the_others(tmp_path):
    """One non-UTF-8 file in a studies folder crashed ``reproduce --list`` and every study (UnicodeDecodeError)."""
    studies = tmp_path / "experiments"
    studies.mkdir()
    (tmp_path / "scenarios").symlink_to(ROOT / "scenarios")
    (studies / "01_nominal.toml").write_text((ROOT / "experiments" / "01_nominal.toml").read_text())
    (studies / "zz_latin1.toml").write_bytes("name = 'caf\u00e9'\n".encode("latin-1"))
    r = runner.invoke(app, ["reproduce", "--list", "--studies-dir", str(studies)])
    assert r.exit_code == 0, r.output
    assert "nominal" in r.output and "zz_latin1.toml" in r.output and "not UTF-8" in r.output
    r = runner.invoke(app, ["reproduce", "--studies-dir", str(studies), "--out", str(tmp_path / "c")])  # all: named
    assert r.exit_code == 2 and "zz_latin1.toml: not UTF-8 text" in r.output
