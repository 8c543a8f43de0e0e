"""``aerorelay codegen`` (issue 62): one relay's controller (the NMPC, the supervisor's envelope, the fail-safe brake
law) as a C tree that builds offline with make (and CMake where installed) against the HPIPM and BLASFEO in CasADi's
wheel, and whose ``replay`` of a Python flight's controller steps gives the Python controller's commands (1e-9
relative; bit for bit where the NMPC flies with the same BLASFEO kernels), with QP failures forced by the file (an
iteration cap) and hand-overs by the supervisor; bad input is a status and a held command, never a crash."""

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

import aerorelay as ar
from aerorelay.api import codegen
from aerorelay.assembly import load_scenario
from aerorelay.cli import app

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()


def _tree(tmp_path: Path, scenario: str, duration: float, *args: str) -> tuple[Path, Path, bool]:
    out, calls = tmp_path / "tree", tmp_path / "calls.csv"
    r = runner.invoke(app, ["codegen", str(ROOT / "scenarios" / scenario), "--out", str(out), "--record", str(calls),
                            "--duration", str(duration), *args])
    assert r.exit_code == 0, r.output
    simd = json.loads((out / "manifest.json").read_text())["simd_here"]  # the kernels the recorded flight ran
    res = subprocess.run(["make", "-C", str(out), f"SIMD={int(simd)}"], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    return out, calls, simd


@pytest.fixture(scope="module")
def nominal_tree(tmp_path_factory):
    """The nominal tilted mission's tree and 2 s of its recorded calls, built once for this module."""
    return _tree(tmp_path_factory.mktemp("nominal"), "nominal_tilted.toml", 2.0, "--no-c-planner")


def _replay(out: Path, calls: Path) -> subprocess.CompletedProcess:
    return subprocess.run([str(out / "build" / "replay"), str(calls)], capture_output=True, text=True)


def _compare(out: Path, calls: Path, simd: bool, steps: int) -> np.ndarray:
    """Replay ``calls`` through the C library; its rows (status, ok, HPIPM status, iterations, brake law, command), checked
    against the Python controller's (brake law, command)."""
    res = _replay(out, calls)
    assert res.returncode == 0, res.stderr
    rows = np.array([[float(v) for v in line.split(",")] for line in res.stdout.splitlines()])
    expected = np.loadtxt(str(calls) + ".expected", delimiter=",", ndmin=2)
    assert rows.shape[0] == expected.shape[0] == steps  # every control period
    np.testing.assert_array_equal(rows[:, 4], expected[:, 0])  # the brake law flies on the same steps
    assert np.all((rows[:, 0] == 4) == (rows[:, 4] == 1))  # AR_FALLBACK exactly when the brake law flies
    # 1e-9 relative; absolute 1e-10 Hz/s where the command is near zero: the brake law's is (sqrt(w2) - Omega) / tau,
    # a difference of ~50 Hz rotor speeds over 0.05 s, and its allocation solved by another SVD than LAPACK's agrees
    # to rounding (measured: 8e-12 Hz/s at most)
    np.testing.assert_allclose(rows[:, 5:], expected[:, 1:], rtol=1e-9, atol=1e-10)
    nmpc = rows[:, 4] == 0
    if simd:  # where the NMPC flies, with the same BLASFEO kernels: the same floating-point operations
        assert np.array_equal(rows[nmpc, 5:], expected[nmpc, 1:])
    return rows


@pytest.mark.parametrize(("scenario", "duration"), [("nominal_tilted.toml", 2.0), ("quad_x.toml", 0.5)])
def test_the_c_controller_gives_the_python_controller_s_commands(tmp_path, nominal_tree, scenario, duration):
    out, calls, simd = (nominal_tree if scenario == "nominal_tilted.toml" else
                        _tree(tmp_path, scenario, duration, "--no-c-planner"))
    rows = _compare(out, calls, simd, math.ceil(duration / 0.015 - 1e-9))
    assert set(rows[:, 0]) <= {0.0, 1.0}  # AR_OK or AR_QP_FAILED (then the shifted plan's input, as in Python)


NOMINAL_C_MIN_GOLDEN = 4.73359e-4  # a golden value: the Python controller's nominal C_min, recorded 2026-12-07 (the
# bounded separation row, docs/results/networks-at-scale.md; 4.7317e-4 before), with the test command's kernel pins


def test_the_nominal_mission_flown_by_the_c_library_keeps_its_c_min(tmp_path):
    """The whole nominal tilted mission with the C library's commands (``--fly``): every command Python's to 1e-9 (bit
    for bit with the same BLASFEO kernels), so its C_min is the Python flight's golden one."""
    out = tmp_path / "tree"
    r = runner.invoke(app, ["codegen", str(ROOT / "scenarios" / "nominal_tilted.toml"), "--out", str(out), "--fly",
                            "--no-c-planner"])
    assert r.exit_code == 0, r.output
    flown = json.loads((out / "fly.json").read_text())
    assert flown["c_steps"] == flown["steps"] > 3000 and flown["c_fallback_steps"] == 0 and not flown["unsafe"]
    assert flown["safety_violations"] == 0 and flown["fallback_episodes"] == 0  # the supervisor never triggers
    assert not flown["planned_in_c"]
    assert flown["c_min"] == pytest.approx(NOMINAL_C_MIN_GOLDEN, abs=5e-9)
    assert flown["max_difference"] < 1e-9 and (flown["max_difference"] == 0.0 or not flown["simd"])


@pytest.mark.parametrize("scenario", ["nominal_tilted.toml", "octo_tilted.toml"])
def test_forced_qp_failures_fly_the_same_brake_law_and_hand_back_the_same(tmp_path, scenario):
    """An iteration cap of 4 fails most QPs (the capacity planner's tracking NMPC): the hand-over after 3 failures, the
    brake law (its bounded least-squares allocation: 8 rotors, 6 rows, so not unique on the octocopter: SciPy's BVLS
    path itself) and the NMPC's return, step for step."""
    duration = 5.0 if scenario == "nominal_tilted.toml" else 2.0  # the NMPC's return: after 4 s
    out, calls, simd = _tree(tmp_path, scenario, duration, "--fly", "--set", "controller.planner=capacity",
                             "--set", "controller.capacity.qp_iter_max=4")
    rows = _compare(out, calls, simd, math.ceil(duration / 0.015))
    statuses = set(rows[:, 0])
    assert {1.0, 4.0} <= statuses  # QP failures and brake-law steps
    assert 0.0 in statuses or scenario != "nominal_tilted.toml"  # the NMPC hands back
    # --fly: the C library's commands flew the plant (the recorded steps are that flight's), Python's beside them
    flown = json.loads((out / "fly.json").read_text())
    assert flown["c_steps"] == rows.shape[0] and flown["c_fallback_steps"] == int(rows[:, 4].sum())
    assert flown["fallback_disagreements"] == 0 and flown["max_difference"] < 1e-9 and not flown["unsafe"]


def test_the_supervisor_s_hand_overs_are_the_same(tmp_path, monkeypatch):
    """mu = 0.99 flips the relay (past validation): the envelope hands over at once, the recovery law rights it."""
    monkeypatch.setattr("aerorelay.assembly.checks._mu_reachable", lambda sc: None)
    out, calls, simd = _tree(tmp_path, "nominal_tilted.toml", 8.0, "--no-c-planner", "--set", "controller.mu=0.99")
    rows = _compare(out, calls, simd, math.ceil(8.0 / 0.015 - 1e-9))
    assert 4.0 in set(rows[:, 0]) and 0.0 in set(rows[:, 0])


def test_bad_input_is_a_status_and_a_held_command(tmp_path, nominal_tree):
    out, calls, _ = nominal_tree
    lines = calls.read_text().splitlines()
    nan_state = lines[0].split(",")
    nan_state[2] = "nan"  # the state's x
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([",".join(nan_state), *lines[:3]]) + "\n")
    res = _replay(out, bad)
    assert res.returncode == 0, res.stderr
    out_rows = [[float(v) for v in line.split(",")] for line in res.stdout.splitlines()]
    assert out_rows[0][0] == 2 and out_rows[0][5:] == [0.0] * 6  # AR_BAD_INPUT, motor accelerations 0: speeds held
    assert all(r[0] == 4 and r[4] == 1 for r in out_rows[1:])  # then the brake law, as after Python's non-finite state
    short = tmp_path / "short.csv"
    short.write_text(lines[0].rsplit(",", 1)[0] + "\n")
    res = _replay(out, short)
    assert res.returncode == 2 and "line 1: 'step' with" in res.stderr


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


def test_the_c_planner_takes_any_number_of_jammers(tmp_path):
    """Two jammers (AR_NJ = 2): the C planner's parameters equal Python's to rounding over 1 s of recorded inputs."""
    out, calls, _ = _tree(tmp_path, "two_jammers.toml", 1.0)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["planner"], manifest["no_planner_because"]
    res = subprocess.run([str(out / "build" / "replay"), "--params", str(calls)], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    rows = np.array([[float(v) for v in line.split(",")] for line in res.stdout.splitlines()])
    params = np.loadtxt(str(calls) + ".params", delimiter=",", ndmin=2)
    nr = manifest["nr"]
    assert rows.shape[0] == params.shape[0] == 67
    assert np.max(np.abs(rows[:, 5 + nr:] - params) / np.maximum(np.abs(params), 1.0)) < 1e-12


@pytest.mark.skipif(shutil.which("aarch64-linux-gnu-gcc") is None and not os.environ.get("AERORELAY_REQUIRE_CROSS"),
                    reason="no aarch64 cross compiler (apt-get install gcc-aarch64-linux-gnu); CI installs it")
def test_the_library_cross_builds_for_aarch64_with_the_tree_s_toolchain_file(tmp_path, nominal_tree):
    """The tree is portable C: its library builds for a 64-bit ARM companion computer with cmake/aarch64-linux-gnu.cmake
    (the programs need HPIPM and BLASFEO built for aarch64 to link)."""
    out, _, _ = nominal_tree
    build = tmp_path / "arm"
    for cmd in (["cmake", "-S", str(out), "-B", str(build), f"-DCMAKE_TOOLCHAIN_FILE={out / 'cmake' / 'aarch64-linux-gnu.cmake'}"],
                ["cmake", "--build", str(build), "--target", "aerorelay_controller"]):
        res = subprocess.run(cmd, capture_output=True, text=True)
        assert res.returncode == 0, res.stdout[-1500:] + res.stderr[-1500:]
    res = subprocess.run(["aarch64-linux-gnu-objdump", "-f", str(build / "libaerorelay_controller.a")], capture_output=True,
                         text=True)
    assert res.returncode == 0 and "elf64-littleaarch64" in res.stdout and "x86-64" not in res.stdout


def test_codegen_refuses_a_folder_that_is_not_empty(tmp_path):
    (tmp_path / "keep.txt").write_text("mine")
    r = runner.invoke(app, ["codegen", str(ROOT / "scenarios" / "nominal_tilted.toml"), "--out", str(tmp_path)])
    assert r.exit_code == 2 and "not an empty folder" in r.output
    assert (tmp_path / "keep.txt").read_text() == "mine"
    # the project's output rules: not below a file (nothing written)
    r = runner.invoke(app, ["codegen", str(ROOT / "scenarios" / "nominal_tilted.toml"), "--out",
                            str(tmp_path / "keep.txt" / "tree")])
    assert r.exit_code == 2 and "is a file, so no folder can be made below it" in r.output


def test_bench_backend_c_times_python_and_the_c_tree_on_the_same_steps(tmp_path):
    """``aerorelay bench --backend c``: rounds of the Python step then the C tree's on the recorded steps (the numbers are
    the bench's to say; here: they exist, for every step, and options that do not apply are refused)."""
    scenario = str(ROOT / "scenarios" / "nominal_tilted.toml")
    out = tmp_path / "bench.json"
    r = runner.invoke(app, ["bench", scenario, "--backend", "c", "--duration", "0.3", "--rounds", "1", "--json", str(out)])
    assert r.exit_code == 0, r.output
    res = json.loads(out.read_text())
    # a step at t = 0, 0.015, ..., 0.3 s: 21
    assert res["steps"] == 21 and len(res["rounds"]) == 1 and res["fallback_steps"] == 0
    rnd = res["rounds"][0]
    for key in ("python_step_ms", "python_preparation_ms", "python_feedback_ms", "c_step_ms", "c_preparation_ms",
                "c_feedback_ms"):
        assert 0 < rnd[key]["p50"] <= rnd[key]["p99"] <= rnd[key]["max"], key
    assert "C step over Python step" in r.output
    r = runner.invoke(app, ["bench", scenario, "--backend", "c", "--ipopt-points", "2"])
    assert r.exit_code == 2 and "--ipopt-points" in r.output
    r = runner.invoke(app, ["bench", scenario, "--rounds", "2"])
    assert r.exit_code == 2 and "--rounds applies to --backend c" in r.output


def test_the_c_planner_makes_python_s_stage_parameters_and_flies_the_same_mission(tmp_path):
    """The paper's planner in C (``ar_plan``: the trajectory generator, its governor, the reference check, the stage
    parameters) from what the Python planner was given: its stage parameters equal Python's to rounding (numpy's
    LAPACK and OpenBLAS order their operations otherwise: measured 4e-16, 8e-12 at most over the whole mission) and
    the commands follow (the RTI carries those roundings on: 2e-10 Hz/s over 2 s); flown with the C planner and
    step, the mission's C_min is Python's within 0.1% (the whole mission: 4.7308e-4 against 4.7317e-4)."""
    out, calls, simd = _tree(tmp_path, "nominal_tilted.toml", 2.0)
    assert json.loads((out / "manifest.json").read_text())["planner"]
    assert calls.read_text().startswith("fly,")
    res = subprocess.run([str(out / "build" / "replay"), "--params", str(calls)], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    rows = np.array([[float(v) for v in line.split(",")] for line in res.stdout.splitlines()])
    expected = np.loadtxt(str(calls) + ".expected", delimiter=",", ndmin=2)
    params = np.loadtxt(str(calls) + ".params", delimiter=",", ndmin=2)
    assert rows.shape[0] == expected.shape[0] == params.shape[0] == 134 and set(rows[:, 0]) == {0.0}
    assert np.max(np.abs(rows[:, 11:] - params) / np.maximum(np.abs(params), 1.0)) < 1e-12
    np.testing.assert_allclose(rows[:, 5:11], expected[:, 1:], rtol=1e-8, atol=1e-8)
    # a source that is not finite: AR_BAD_INPUT from the planner, the line still a step
    fields = calls.read_text().splitlines()[5].split(",")
    fields[2 + 1 + 18 + 6] = "nan"  # fly, t, shift, x (18), u_prev (6), the source's x
    bad = tmp_path / "bad.csv"
    bad.write_text(",".join(fields) + "\n")
    res = subprocess.run([str(out / "build" / "replay"), str(bad)], capture_output=True, text=True)
    assert res.returncode == 0 and res.stdout.split(",")[0] == "2", res.stdout + res.stderr
    # flown: 6 s with the C planner and the C step against the Python flight
    sc = load_scenario(ROOT / "scenarios" / "nominal_tilted.toml", set={"sim.duration_s": 6.0})
    summary = codegen(sc, tmp_path / "flown", fly=True)
    flown = summary["flown"]
    assert flown["planned_in_c"] and flown["max_parameter_difference"] < 1e-12 and not flown["unsafe"]
    python = ar.simulate(sc).metrics
    assert flown["c_min"] == pytest.approx(python["c_min"], rel=1e-3)
    assert flown["c_mean"] == pytest.approx(python["c_mean"], rel=1e-3)


def test_bench_reads_what_record_writes_and_replay_reads_whole_numbers_only(tmp_path):
    """The guide's first command records ``fly`` events (the tree has the paper's planner): ``build/bench`` refused them
    ("line 1 is not a step"); it now reads their stage parameters from the recording's ``.params``. ``replay`` read
    "-6.951.5abc" as -6.951."""
    out, calls, _ = _tree(tmp_path, "nominal_tilted.toml", 0.3)
    assert calls.read_text().startswith("fly,")
    res = subprocess.run([str(out / "build" / "bench"), str(calls), "1"], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    rows = np.loadtxt(res.stdout.splitlines(), delimiter=",", ndmin=2)
    assert rows.shape == (len(calls.read_text().splitlines()), 6) and np.all(rows[:, 2] > 0)  # every step timed
    assert np.all(rows[:, 5] >= 1) and np.all(rows[:, 5] == np.round(rows[:, 5]))  # its IPM iterations, each step's
    for rounds in ("0", "2x"):
        assert subprocess.run([str(out / "build" / "bench"), str(calls), rounds], capture_output=True, text=True).returncode == 2
    bad = tmp_path / "bad.csv"
    lines = calls.read_text().splitlines()
    fields = lines[0].split(",")
    fields[3] = fields[3] + ".5abc"  # the state's first number spoiled
    bad.write_text(",".join(fields) + "\n")
    res = _replay(out, bad)
    assert res.returncode == 2 and "no step" in res.stderr
