"""``aerorelay codegen`` (issue 62, its first part): one relay's NMPC as a C tree that builds offline with make (and
CMake where installed) against the HPIPM and BLASFEO in CasADi's wheel, and whose ``replay`` of a Python flight's
NMPC calls gives the Python NMPC's commands (1e-9 relative; bit for bit when built with the same BLASFEO kernels);
bad input is a status and a held command, never a crash."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from aerorelay.cli import app

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()


def _tree(tmp_path: Path, scenario: str, duration: float) -> tuple[Path, Path, bool]:
    out, calls = tmp_path / "tree", tmp_path / "calls.csv"
    r = runner.invoke(app, ["codegen", str(ROOT / "scenarios" / scenario), "--out", str(out), "--record", str(calls),
                            "--duration", str(duration)])
    assert r.exit_code == 0, r.output
    simd = json.loads((out / "manifest.json").read_text())["simd_here"]  # the kernels the recorded flight ran
    res = subprocess.run(["make", "-C", str(out), f"SIMD={int(simd)}"], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    return out, calls, simd


@pytest.fixture(scope="module")
def nominal_tree(tmp_path_factory):
    """The nominal tilted mission's tree and 2 s of its recorded calls, built once for this module."""
    return _tree(tmp_path_factory.mktemp("nominal"), "nominal_tilted.toml", 2.0)


def _replay(out: Path, calls: Path) -> subprocess.CompletedProcess:
    return subprocess.run([str(out / "build" / "replay"), str(calls)], capture_output=True, text=True)


@pytest.mark.parametrize(("scenario", "duration"), [("nominal_tilted.toml", 2.0), ("quad_x.toml", 0.5)])
def test_the_c_controller_gives_the_python_nmpc_s_commands(tmp_path, nominal_tree, scenario, duration):
    out, calls, simd = nominal_tree if scenario == "nominal_tilted.toml" else _tree(tmp_path, scenario, duration)
    res = _replay(out, calls)
    assert res.returncode == 0, res.stderr
    rows = np.array([[float(v) for v in line.split(",")] for line in res.stdout.splitlines()])
    expected = np.loadtxt(str(calls) + ".expected", delimiter=",", ndmin=2)
    assert rows.shape[0] == expected.shape[0] == math.ceil(duration / 0.015 - 1e-9)  # every control period
    assert set(rows[:, 0]) <= {0.0, 1.0}  # AR_OK or AR_QP_FAILED (then the shifted plan's input, as in Python)
    np.testing.assert_allclose(rows[:, 4:], expected, rtol=1e-9, atol=1e-12)
    if simd:  # the same BLASFEO kernels: the same floating-point operations
        assert np.array_equal(rows[:, 4:], expected)


def test_bad_input_is_a_status_and_a_held_command(tmp_path, nominal_tree):
    out, calls, _ = nominal_tree
    lines = calls.read_text().splitlines()
    fb = next(k for k, line in enumerate(lines) if line.startswith("feedback,"))
    nan_state = lines[fb].split(",")
    nan_state[2] = "nan"  # the state's x
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([*lines[:fb], ",".join(nan_state), *lines[fb:]]) + "\n")
    res = _replay(out, bad)
    assert res.returncode == 0, res.stderr
    first = [float(v) for v in res.stdout.splitlines()[0].split(",")]
    assert first[0] == 2 and first[4:] == [0.0] * 6  # AR_BAD_INPUT, motor accelerations 0: the rotor speeds held
    short = tmp_path / "short.csv"
    short.write_text(lines[fb].rsplit(",", 1)[0] + "\n")
    res = _replay(out, short)
    assert res.returncode == 2 and "line 1: 'feedback' with" in res.stderr


@pytest.mark.skipif(shutil.which("cmake") is None and not os.environ.get("AERORELAY_REQUIRE_CMAKE"),
                    reason="no cmake on this machine (make builds the tree); CI installs it and requires this test")
def test_the_tree_builds_with_cmake_too(tmp_path, nominal_tree):
    out, calls, _ = nominal_tree
    build = tmp_path / "cmake-build"
    for cmd in (["cmake", "-S", str(out), "-B", str(build)], ["cmake", "--build", str(build)]):
        res = subprocess.run(cmd, capture_output=True, text=True)
        assert res.returncode == 0, res.stdout[-1500:] + res.stderr[-1500:]
    res = subprocess.run([str(build / "replay"), str(calls)], capture_output=True, text=True)
    assert res.returncode == 0 and len(res.stdout.splitlines()) == math.ceil(2.0 / 0.015 - 1e-9)


def test_codegen_refuses_a_folder_that_is_not_empty(tmp_path):
    (tmp_path / "keep.txt").write_text("mine")
    r = runner.invoke(app, ["codegen", str(ROOT / "scenarios" / "nominal_tilted.toml"), "--out", str(tmp_path)])
    assert r.exit_code == 2 and "not an empty folder" in r.output
    assert (tmp_path / "keep.txt").read_text() == "mine"
