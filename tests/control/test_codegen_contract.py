"""The C library's contract (issue 77): a NULL, destroyed or never-created controller, or a NULL array, is AR_BAD_INPUT
and never a dereference; a command no vehicle flies gives no setpoint; the planner refuses a time that is not finite
and a jammer power below zero. Checked by ``tests/control/c/contract.c`` built with the library under AddressSanitizer
and UndefinedBehaviorSanitizer (a read of freed memory or a NULL dereference aborts the program)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

import aerorelay as ar
from aerorelay.api import codegen
from aerorelay.control.hpipm_rti import _casadi_dir

ROOT = Path(__file__).resolve().parents[2]
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
    without the name, or with a name not in the network, a named error before anything is written; recording or
    flying a network's tree is refused (the tree would stand in for every relay)."""
    import json

    import aerorelay as ar
    from aerorelay.assembly.parts import build

    sc = ar.load_scenario("scenarios/chain_two_relays.toml", set={"network.route": False})
    with pytest.raises(ValueError, match=r"--relay: the network has relays r1, r2"):
        ar.api.codegen(sc, tmp_path / "none")
    with pytest.raises(ValueError, match=r"--relay 'r9': the scenario's relays are r1, r2"):
        ar.api.codegen(sc, tmp_path / "none", relay="r9")
    with pytest.raises(ValueError, match=r"--record / --fly: .* 2 relays"):
        ar.api.codegen(sc, tmp_path / "none", relay="r2", record=tmp_path / "steps.csv")
    assert not (tmp_path / "none").exists()
    summary = ar.api.codegen(sc, tmp_path / "r2", relay="r2")
    manifest = json.loads((tmp_path / "r2" / "manifest.json").read_text())
    assert manifest["relay"] == "r2" and "relay `r2`" in (tmp_path / "r2" / "README.md").read_text()
    r2 = next(r for r in build(sc).relays if r.name == "r2").stepper.controller.spec
    assert summary["n_params"] == r2.n_params and summary["horizon"] == r2.horizon
