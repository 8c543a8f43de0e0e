"""The C library's contract (issue 77): a NULL, destroyed or never-created controller, or a NULL array, is AR_BAD_INPUT
and never a dereference; a command no vehicle flies gives no setpoint; the planner refuses a time that is not finite
and a jammer power below zero. Checked by ``tests/control/c/contract.c`` built with the library under AddressSanitizer
and UndefinedBehaviorSanitizer (a read of freed memory or a NULL dereference aborts the program)."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.api import codegen
from aerorelay.control.hpipm_rti import _casadi_dir

ROOT = Path(__file__).resolve().parents[2]
INTERPOSED = {"kernel_dgemm_nt_4x4_lib4", "kernel_dgemm_nn_4x4_lib4", "aerorelay_simd_kernels_ran"}
SANITIZE = "-O0 -g -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=undefined"


@pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler")
@pytest.mark.parametrize("scenario", ["nominal_tilted.toml"])  # the paper's planner in the tree (ar_plan too)
def test_the_c_library_refuses_bad_pointers_and_values_under_the_sanitizers(tmp_path, scenario):
    sc = ar.load_scenario(ROOT / "scenarios" / scenario, set={"sim.duration_s": 0.1})
    tree = tmp_path / "tree"
    codegen(sc, tree)
    make = subprocess.run(["make", "-C", str(tree), f"CFLAGS={SANITIZE}", "build/libaerorelay_controller.a"],
                          capture_output=True, text=True)
    assert make.returncode == 0, make.stderr[-2000:]
    cdir = _casadi_dir()
    exe = tmp_path / "contract"
    build = subprocess.run(["cc", *SANITIZE.split(), f"-I{tree / 'include'}", str(ROOT / "tests" / "control" / "c" / "contract.c"),
                            str(tree / "build" / "libaerorelay_controller.a"), f"-L{cdir}", "-lhpipm", "-lblasfeo", "-lm",
                            f"-Wl,-rpath,{cdir}", "-o", str(exe)], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr[-2000:]
    run = subprocess.run([str(exe)], capture_output=True, text=True, env={"ASAN_OPTIONS": "detect_leaks=1",
                                                                          "UBSAN_OPTIONS": "print_stacktrace=1"})
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    assert "0 failed" in run.stdout and "FAILED" not in run.stdout
    assert "ar_step after ar_destroy" in run.stdout


def test_a_networks_tree_is_the_named_relays_and_never_relay_0_silently(tmp_path):
    """Issue 78: a network's C tree is the relay ``--relay`` names (its own OCP: the chain's r2 sees its neighbours);
    without the name, or with a name not in the network, a named error before anything is written."""
    import json

    import aerorelay as ar
    from aerorelay.assembly.parts import build

    sc = ar.load_scenario("scenarios/chain_two_relays.toml", set={"network.route": False})
    with pytest.raises(ValueError, match=r"--relay: the network has relays r1, r2"):
        ar.api.codegen(sc, tmp_path / "none")
    with pytest.raises(ValueError, match=r"--relay 'r9': the scenario's relays are r1, r2"):
        ar.api.codegen(sc, tmp_path / "none", relay="r9")
    assert not (tmp_path / "none").exists()
    summary = ar.api.codegen(sc, tmp_path / "r2", relay="r2")
    manifest = json.loads((tmp_path / "r2" / "manifest.json").read_text())
    assert manifest["relay"] == "r2" and "relay `r2`" in (tmp_path / "r2" / "README.md").read_text()
    r2 = next(r for r in build(sc).relays if r.name == "r2").stepper.controller.spec
    assert summary["n_params"] == r2.n_params and summary["horizon"] == r2.horizon


@pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler")
def test_two_relays_trees_link_into_one_program_and_each_replays_its_relay_to_1e_9(tmp_path):
    """Issue 78: the chain's two relays' trees (``--prefix r1`` / ``r2``), both headers in one translation unit
    (``tests/control/c/two_trees.c``), both libraries linked into one program, both controllers alive at once, one
    step of each in turn: each gives its relay's Python commands (recorded by ``--record`` from one flight of the
    network each) to 1e-9; every global symbol of each library begins with its prefix (``nm``)."""
    sc = ar.load_scenario(ROOT / "scenarios" / "chain_two_relays.toml", set={"network.route": False, "sim.duration_s": 0.6})
    simd = {}
    for relay in ("r1", "r2"):
        summary = codegen(sc, tmp_path / relay, relay=relay, prefix=relay, record=tmp_path / f"{relay}.csv")
        assert summary["prefix"] == relay and summary["recorded"] == len((tmp_path / f"{relay}.csv").read_text().splitlines()) >= 40
        simd[relay] = int(json.loads((tmp_path / relay / "manifest.json").read_text())["simd_here"])
        make = subprocess.run(["make", "-C", str(tmp_path / relay), f"SIMD={simd[relay]}", "build/libaerorelay_controller.a"],
                              capture_output=True, text=True)
        assert make.returncode == 0, make.stderr[-2000:]
        if shutil.which("nm"):
            nm = subprocess.run(["nm", "-g", "--defined-only", str(tmp_path / relay / "build" / "libaerorelay_controller.a")],
                                capture_output=True, text=True, check=True).stdout
            symbols = [line.split()[1:] for line in nm.splitlines() if len(line.split()) == 3]
            # every strong name the tree's; BLASFEO's two interposed kernels and their flag weak (one in a program)
            strong = [n for kind, n in symbols if kind not in ("W", "V")]
            assert strong and all(n.startswith(f"{relay}_") for n in strong), [n for n in strong if not n.startswith(relay)]
            assert {n for kind, n in symbols if kind in ("W", "V")} <= INTERPOSED
    # each relay's recording is its own: the two relays' commands differ
    assert (tmp_path / "r1.csv").read_text() != (tmp_path / "r2.csv").read_text()
    cdir = _casadi_dir()
    exe = tmp_path / "two_trees"
    build = subprocess.run(["cc", "-O2", f"-I{tmp_path}", str(ROOT / "tests" / "control" / "c" / "two_trees.c"),
                            *(str(tmp_path / r / "build" / "libaerorelay_controller.a") for r in ("r1", "r2")),
                            f"-L{cdir}", "-lhpipm", "-lblasfeo", "-lm", f"-Wl,-rpath,{cdir}", "-o", str(exe)],
                           capture_output=True, text=True)
    assert build.returncode == 0, build.stderr[-3000:]
    run = subprocess.run([str(exe), str(tmp_path / "r1.csv"), str(tmp_path / "r2.csv")], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-2000:]
    rows = np.array([[float(v) for v in line.split(",")] for line in run.stdout.splitlines()])
    for tree in (1, 2):
        mine = rows[rows[:, 0] == tree]
        expected = np.loadtxt(tmp_path / f"r{tree}.csv.expected", delimiter=",", ndmin=2)
        assert mine.shape[0] == expected.shape[0] >= 40
        np.testing.assert_array_equal(mine[:, 1], expected[:, 0])  # the brake law on the same steps
        np.testing.assert_allclose(mine[:, 2:], expected[:, 1:], rtol=1e-9, atol=1e-10)


def test_a_prefix_that_cannot_begin_c_names_is_refused_before_any_work(tmp_path):
    sc = ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml")
    for bad in ("R1", "1r", "r1_", "r__1", "d", "hpipm", "a" * 25, ""):
        with pytest.raises(ValueError, match=r"--prefix: .*lowercase letter"):
            codegen(sc, tmp_path / "tree", prefix=bad)
        assert not (tmp_path / "tree").exists()


def test_a_template_and_its_caller_agree_on_every_placeholder():
    """The tree's text files are templates (``assembly/templates``): a placeholder left without a value, or a value
    given for none, is an error, never a literal ``{{name}}`` in a tree or a setting silently dropped."""
    from aerorelay.assembly.codegen import render

    assert "#define AR_NJ 3" in render("planner_api.h.in", jammers=3)
    with pytest.raises(ValueError, match=r"placeholders \['jammers'\] have no value"):
        render("planner_api.h.in")
    with pytest.raises(ValueError, match=r"values \['extra'\] no placeholder"):
        render("planner_api.h.in", jammers=3, extra=1)
