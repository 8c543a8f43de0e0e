"""Fault injection: bad outputs, corrupt caches and run folders, unsafe flights, bad missions.

Each case checks the named error (and exit code), that nothing outside the program's own folders
changed, and that a relay that leaves its world is reported as unsafe, never as done."""

import json
import os
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import aerorelay as ar
from aerorelay.assembly import load_scenario
from aerorelay.cli import EXIT_BAD_INPUT, EXIT_UNSAFE, app
from aerorelay.config import ScenarioError
from aerorelay.experiments.campaign import LOCK_FILE, CampaignBusyError, is_finished, load_manifest, run_campaign, run_dir
from aerorelay.experiments.study import RunSpec
from aerorelay.store.cache import entry_is_intact
from aerorelay.store.codegen import shared_library
from aerorelay.store.outputs import MARKER, OutputError, check_output_folder, mark

ROOT = Path(__file__).resolve().parents[2]
NOMINAL = ROOT / "scenarios" / "nominal_tilted.toml"
runner = CliRunner()


def run_cli(*args):
    return runner.invoke(app, [str(a) for a in args])


def snapshot(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


# ---------------------------------------------------------------- never delete what we did not write
def test_run_refuses_a_folder_with_someone_elses_files(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("years of work")
    before = snapshot(tmp_path)
    res = run_cli("run", NOMINAL, "--out", out, "--duration", "0.3", "--no-figures", "--no-bound")
    assert res.exit_code == EXIT_BAD_INPUT and "did not write" in res.output
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("where", [".", "home", "git"])
def test_forbidden_output_places(tmp_path, monkeypatch, where):
    monkeypatch.chdir(tmp_path)
    if where == "home":
        monkeypatch.setenv("HOME", str(tmp_path / "h"))
        (tmp_path / "h").mkdir()
        target = tmp_path / "h"
    elif where == "git":
        target = tmp_path / "repo"
        (target / ".git").mkdir(parents=True)
    else:
        target = Path(".")
    with pytest.raises(OutputError):
        check_output_folder(target, "run")


def test_out_that_is_a_file_or_unwritable_fails_before_flying(tmp_path):
    f = tmp_path / "afile"
    f.write_text("x")
    res = run_cli("run", NOMINAL, "--out", f, "--duration", "0.3", "--no-bound")
    assert res.exit_code == EXIT_BAD_INPUT and "is a file" in res.output and f.read_text() == "x"
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if not os.access(ro, os.W_OK):  # a user the permission bits hold: the real case
            res = run_cli("run", NOMINAL, "--out", ro / "x", "--duration", "0.3", "--no-bound")
            assert res.exit_code == EXIT_BAD_INPUT and "not writable" in res.output
    finally:
        ro.chmod(0o700)


def test_an_unwritable_out_fails_before_flying_for_root_too(tmp_path, monkeypatch):
    """Root ignores permission bits (CI runs as root): the product's own access check answers "no" for
    that folder, so the branch runs everywhere; nothing is written."""
    import aerorelay.store.outputs as outputs

    ro = tmp_path / "ro"
    ro.mkdir()
    real = outputs.os.access
    monkeypatch.setattr(outputs.os, "access", lambda p, mode: False if Path(p) == ro else real(p, mode))
    res = run_cli("run", NOMINAL, "--out", ro / "x", "--duration", "0.3", "--no-bound")
    assert res.exit_code == EXIT_BAD_INPUT and "is not writable (nothing was written)" in " ".join(res.output.split())
    assert list(ro.iterdir()) == []


def test_not_enough_disk_is_a_named_error(tmp_path):
    with pytest.raises(OutputError, match="MB free"):
        check_output_folder(tmp_path / "x", "run", need_bytes=10**18)


def test_an_own_run_folder_is_replaced_atomically(tmp_path):
    out = tmp_path / "run"
    for _ in range(2):
        res = run_cli("run", NOMINAL, "--out", out, "--duration", "0.3", "--no-figures", "--no-bound")
        assert res.exit_code == 0, res.output
    assert (out / MARKER).is_file() and (out / "metrics.json").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # no temporary or old folder left behind


def test_huge_duration_is_a_named_error_before_any_work(tmp_path):
    res = run_cli("run", NOMINAL, "--out", tmp_path / "r", "--duration", "1e9", "--no-bound")
    assert res.exit_code == EXIT_BAD_INPUT and "sim.duration_s" in res.output and not (tmp_path / "r").exists()


# ---------------------------------------------------------------- inputs
@pytest.mark.parametrize("body,needle", [
    ("t,px,py,pz,vx,vy,vz,ax,ay,az\n0,1,1,1,0,0,0,0,0,0\n1,nan,1,1,0,0,0,0,0,0\n", "not a finite number"),
    ("t,px,py,pz,vx,vy,vz,ax,ay,az\n0,1,1,1,0,0,0,0,0,0\n1,inf,1,1,0,0,0,0,0,0\n", "not a finite number"),
    ("t,px,py,pz,vx,vy,vz,ax,ay,az\n0,1,1,1,0,0,0,0,0,0\n1,abc,1,1,0,0,0,0,0,0\n", "not a finite number"),
    ("t,px,py,pz,vx,vy,vz,ax,ay,az\n", "at least 2 rows"),
    ("t,px,py,pz,vx,vy,vz,ax,ay,az\n0,1,1,1,0,0,0,0,0,0\n", "at least 2 rows"),
    ("", "not a readable CSV"),
    ("t,px,py,pz,vx,vy,vz,ax,ay,az\n1,1,1,1,0,0,0,0,0,0\n0,1,1,1,0,0,0,0,0,0\n", "strictly increasing"),
])
def test_csv_missions_are_checked_at_load_and_for_set(tmp_path, body, needle):
    csv = tmp_path / "m.csv"
    csv.write_text(body)
    with pytest.raises(ScenarioError, match=f"mission.trajectory_csv: .*{needle}"):
        load_scenario(NOMINAL, set={"mission.trajectory_csv": str(csv)})
    sc = load_scenario(NOMINAL)
    with pytest.raises(ScenarioError, match="mission.trajectory_csv"):
        sc.with_updates({"mission.trajectory_csv": str(csv)})


@pytest.mark.parametrize("sets,field", [
    ({"controller.horizon": 1}, "controller"), ({"controller.ts_s": 1.0}, "controller.ts_s"),
    ({"platform.omega_max_hz": 62.0}, "platform"), ({"platform.omega_dot_max_hz_s": 1.0}, "platform.omega_dot_max_hz_s"),
    ({"mission.waypoints": [[0, -3, 5, 1.7], [10, -3, 5, -2.0]]}, "mission.waypoints"),
    ({"platform.rotors": [{"position": [0.3 * k, 0, 0], "axis": [0, 0, 1], "spin": (-1) ** k} for k in (-2, -1, 1, 2)]}, "platform"),
    ({"platform.rotors": [{"position": [0.3, 0, 0], "axis": [0, 0, 0], "spin": 1}] * 4}, "platform.rotors.0.axis"),
    ({"name.x": 1}, "name.x"),
])
def test_scenarios_that_cannot_fly_safely_are_rejected_with_the_field(sets, field):
    with pytest.raises(ScenarioError, match=field.replace(".", r"\.")):
        load_scenario(NOMINAL, set=sets)


def test_deeply_nested_toml_is_a_named_error(tmp_path):
    f = tmp_path / "deep.toml"
    f.write_text("a" + "={a" * 3000 + "}" * 3000)
    with pytest.raises(ScenarioError, match="nested too deeply"):
        load_scenario(f)


def test_compare_on_a_corrupt_metrics_file(tmp_path):
    for d in ("a", "b"):
        (tmp_path / d).mkdir()
        (tmp_path / d / "metrics.json").write_text("{trunc")
    res = run_cli("compare", tmp_path / "a", tmp_path / "b")
    assert res.exit_code == EXIT_BAD_INPUT and "metrics.json: not readable JSON" in " ".join(res.output.split())


# ---------------------------------------------------------------- caches
def test_a_truncated_compiled_library_is_rebuilt(tmp_path, monkeypatch):
    monkeypatch.setenv("AERORELAY_CACHE", str(tmp_path / "cache"))
    from aerorelay.store import cache

    cache._usable.cache_clear()
    src = "int answer(void) { return 42; }\n"
    lib = shared_library("probe", src, "k")
    assert entry_is_intact(lib)
    lib.write_bytes(lib.read_bytes()[:100])  # truncated: loading it would crash with SIGBUS
    assert not entry_is_intact(lib)
    again = shared_library("probe", src, "k")
    assert again == lib and entry_is_intact(lib) and lib.stat().st_size > 100
    cache._usable.cache_clear()


def test_a_truncated_bound_is_recomputed(tmp_path, monkeypatch):
    monkeypatch.setenv("AERORELAY_CACHE", str(tmp_path / "cache"))
    from aerorelay.store import cache

    cache._usable.cache_clear()
    sc = load_scenario(NOMINAL, set={"sim.duration_s": 1.0, "bound.grid_m": 2.0, "bound.dt_s": 0.5})
    first = ar.bound(sc)
    (entry,) = (tmp_path / "cache" / "bounds").glob("*.npz")
    entry.write_bytes(entry.read_bytes()[:50])
    again = ar.bound(sc)
    np.testing.assert_array_equal(first.static, again.static)
    assert entry_is_intact(entry)
    cache._usable.cache_clear()


def test_an_unwritable_cache_falls_back_to_a_temporary_one(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("AERORELAY_CACHE", str(blocker / "cache"))  # cannot be created: a file is in the way
    from aerorelay.store import cache

    cache._usable.cache_clear()
    try:
        assert cache.cache_dir() != blocker / "cache" and os.access(cache.cache_dir(), os.W_OK)
    finally:
        cache._usable.cache_clear()


# ---------------------------------------------------------------- campaigns
def _spec(tmp_path) -> RunSpec:
    sc = load_scenario(NOMINAL, set={"sim.duration_s": 0.3, "name": "faults/r"})
    return RunSpec("faults", "r", 0, sc.to_toml(), False)


def test_resume_verifies_every_file_and_recomputes_a_broken_run(tmp_path):
    spec, out = _spec(tmp_path), tmp_path / "camp"
    run_campaign([spec], out, n_workers=1)
    assert is_finished(out, spec)
    d = run_dir(out, spec)
    for damage in ("truncate", "empty", "remove"):
        ts = d / "timeseries.parquet"
        if damage == "truncate":
            ts.write_bytes(ts.read_bytes()[:200])
        elif damage == "empty":
            ts.write_bytes(b"")
        else:
            ts.unlink()
        assert not is_finished(out, spec)
        res = run_campaign([spec], out, n_workers=1)
        assert res.ran == 1 and is_finished(out, spec), damage


def test_a_corrupt_manifest_is_rebuilt(tmp_path):
    spec, out = _spec(tmp_path), tmp_path / "camp"
    run_campaign([spec], out, n_workers=1)
    for bad in ("{trunc", "[]"):
        (out / "manifest.json").write_text(bad)
        res = run_campaign([spec], out, n_workers=1)
        assert res.skipped == 1 and load_manifest(out)[spec.key]["status"] == "done"


def test_one_campaign_per_folder(tmp_path):
    import fcntl

    spec, out = _spec(tmp_path), tmp_path / "camp"
    out.mkdir()
    mark(out, "campaign")  # as the running campaign has
    with open(out / LOCK_FILE, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        with pytest.raises(CampaignBusyError, match="another campaign"):
            run_campaign([spec], out, n_workers=1)


def test_reproduce_refuses_a_file_and_bad_worker_counts(tmp_path):
    f = tmp_path / "f"
    f.write_text("x")
    res = run_cli("reproduce", "nominal", "--out", f, "--quick")
    assert res.exit_code == EXIT_BAD_INPUT and f.read_text() == "x"
    res = run_cli("reproduce", "nominal", "--out", tmp_path / "c", "--workers", "-1")
    assert res.exit_code == EXIT_BAD_INPUT and "--workers" in res.output and "x>=1" in res.output
    assert not (tmp_path / "c").exists()


def test_an_unreachable_scheduler_is_a_named_error(tmp_path):
    res = run_cli("reproduce", "nominal", "--out", tmp_path / "c", "--quick", "--scheduler", "tcp://127.0.0.1:9")
    assert res.exit_code == EXIT_BAD_INPUT and "no dask scheduler answers" in res.output


# ---------------------------------------------------------------- flight safety
@pytest.mark.parametrize("preset, mu", [("nominal_tilted", 0.99), ("nominal_tilted", 0.61), ("nominal_coplanar", 0.42)])
def test_an_alignment_threshold_beyond_the_platforms_reach_is_rejected_before_flying(tmp_path, preset, mu):
    """mu above the mutual alignment the relay can reach in hover anywhere in its workspace (0.606 tilted,
    0.416 coplanar on the nominal mission) drove the relay out of the box: exit 2, the field and the
    allowed range named, nothing written."""
    out = tmp_path / "r"
    res = run_cli("run", ROOT / "scenarios" / f"{preset}.toml", "--out", out, "--set", f"controller.mu={mu}")
    assert res.exit_code == EXIT_BAD_INPUT and not out.exists(), res.output
    assert "controller.mu" in res.output and "use mu in (0, " in res.output


def test_the_capacity_planner_and_the_unconstrained_variant_do_not_need_a_reachable_mu():
    """Only the paper's comms-aware NMPC carries the alignment constraint."""
    load_scenario(NOMINAL, set={"controller.mu": 0.99, "controller.planner": "capacity"})
    load_scenario(NOMINAL, set={"controller.mu": 0.99, "controller.variant": "unconstrained"})


@pytest.fixture
def unchecked_mu(monkeypatch):
    """The reach check off: the layers behind validation must hold on their own."""
    monkeypatch.setattr("aerorelay.assembly.checks._mu_reachable", lambda sc: None)


def test_a_relay_that_leaves_its_world_is_reported_unsafe_with_its_exit_code(tmp_path, unchecked_mu):
    """Without the supervisor (and past validation) the weights that flip the relay (mu = 0.99) send it out
    of the box; the run is marked unsafe (metrics, exit code) whatever the QPs said."""
    out = tmp_path / "r"
    res = run_cli("run", NOMINAL, "--out", out, "--duration", "10", "--no-figures", "--no-bound",
                  "--set", "controller.mu=0.99", "--set", "controller.failsafe.supervisor=false")
    m = json.loads((out / "metrics.json").read_text())
    assert m["unsafe"] and m["box_violation_max_m"] > 0.05 and res.exit_code == EXIT_UNSAFE, res.output


def test_the_supervisor_hands_over_at_once_and_the_brake_law_recovers_the_attitude(tmp_path, unchecked_mu):
    sc = load_scenario(NOMINAL, set={"controller.mu": 0.99, "sim.duration_s": 20.0})
    r = ar.simulate(sc)
    df, m = r.timeseries, r.metrics
    assert m["safety_violations"] > 0 and df["relay.fallback"].any()
    first = int(np.argmax(df["relay.safety_violation"].to_numpy()))
    assert df["relay.fallback"].iloc[first]  # the same step, not after 3 failed QPs
    assert m["min_altitude_m"] > 0.5 and m["max_tilt_deg"] < 90.0  # never flipped, never below the floor


@pytest.mark.parametrize(("preset", "planner"), [("nominal_coplanar", "trajectory_generator"),
                                               ("nominal_tilted", "capacity"), ("nominal_coplanar", "capacity")])
def test_the_supervisor_never_triggers_on_the_nominal_presets(preset, planner):
    """(The nominal tilted mission with the paper's planner: tests/control/test_codegen.py flies it whole, its safety
    violations and brake-law steps 0, with the C library's commands and Python's beside.)"""
    m = ar.simulate(load_scenario(ROOT / "scenarios" / f"{preset}.toml", set={"controller.planner": planner})).metrics
    assert m["safety_violations"] == 0 and m["fallback_fraction"] == 0.0 and not m["unsafe"]
    assert m["box_violation_max_m"] == 0.0
