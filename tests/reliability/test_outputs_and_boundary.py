"""One writer per output folder, links followed, leftovers of a killed writer cleaned up, strict
JSON everywhere; the Python API's objects checked at the boundary with named errors."""

import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from typer.testing import CliRunner

import aerorelay as ar
from aerorelay.assembly import load_scenario
from aerorelay.cli import EXIT_BAD_INPUT, app
from aerorelay.config import ScenarioError
from aerorelay.models.checks import InvalidInput
from aerorelay.planning.base import PlannerFailed
from aerorelay.store import strict_json
from aerorelay.store.outputs import OutputBusyError, clean_stale_siblings, lock_path, new_sibling, writing

ROOT = Path(__file__).resolve().parents[2]
NOMINAL = ROOT / "scenarios" / "nominal_tilted.toml"
runner = CliRunner()
HOLD = ("import sys, time; from aerorelay.store.outputs import writing\n"
        "with writing(sys.argv[1]):\n    print('held', flush=True); time.sleep(float(sys.argv[2]))\n")


def run_cli(*args):
    return runner.invoke(app, [str(a) for a in args])


def _holder(folder: Path, seconds: float) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", HOLD, str(folder), str(seconds)], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "held"
    return proc


# ---------------------------------------------------------------- one writer per folder
@pytest.mark.parametrize("command", ["run", "bound"])
def test_a_second_writer_gets_a_named_error(tmp_path, command):
    out = tmp_path / "r"
    proc = _holder(out, 30)
    try:
        extra = ["--duration", "0.3", "--no-bound", "--no-figures"] if command == "run" else []
        res = run_cli(command, NOMINAL, "--out", out, *extra)
        assert res.exit_code == EXIT_BAD_INPUT and "another aerorelay process" in res.output
    finally:
        proc.kill()
        proc.wait()


def test_wait_takes_the_folder_once_the_other_writer_is_done(tmp_path):
    out = tmp_path / "r"
    proc = _holder(out, 1.5)
    t0 = time.monotonic()
    res = run_cli("run", NOMINAL, "--out", out, "--duration", "0.3", "--no-bound", "--no-figures", "--wait")
    proc.wait()
    assert res.exit_code == 0, res.output
    assert time.monotonic() - t0 >= 1.0 and (out / "metrics.json").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]  # the lock file goes with its holder


def test_the_api_save_refuses_a_folder_another_process_writes(tmp_path):
    res = ar.simulate(load_scenario(NOMINAL, set={"sim.duration_s": 0.3}))
    out = tmp_path / "r"
    proc = _holder(out, 30)
    try:
        with pytest.raises(OutputBusyError):
            res.save(out, figures=False)
    finally:
        proc.kill()
        proc.wait()
    res.save(out, figures=False)
    assert (out / "metrics.json").is_file()


def test_the_same_process_may_nest_the_lock(tmp_path):
    with writing(tmp_path / "r") as a, writing(tmp_path / "r") as b:
        assert a == b and lock_path(a).exists()
    assert not lock_path(tmp_path / "r").exists()


@pytest.mark.parametrize("target_exists", [True, False])
def test_an_output_that_is_a_link_is_written_where_it_points(tmp_path, target_exists):
    target = tmp_path / "real"
    if target_exists:
        target.mkdir()
    link = tmp_path / "link"
    link.symlink_to(target, target_is_directory=True)
    for _ in range(2):  # twice: the second run replaces the first, through the link
        res = run_cli("run", NOMINAL, "--out", link, "--duration", "0.3", "--no-bound", "--no-figures")
        assert res.exit_code == 0, res.output
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert (target / "metrics.json").is_file()


# ---------------------------------------------------------------- what a killed writer leaves
def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_a_killed_writers_leftovers_are_cleaned_by_the_next_one(tmp_path):
    out = tmp_path / "r"
    dead = _dead_pid()
    stale = [tmp_path / f".r.tmp-{dead}-abc", tmp_path / f".r.old-{dead}-123"]
    live = tmp_path / f".r.tmp-{os.getppid()}-xyz"  # a live process's: left alone
    foreign = tmp_path / ".r.mine"  # not a name this program makes: left alone
    for d in (*stale, live, foreign):
        d.mkdir()
        (d / "f").write_text("x")
    tmp = new_sibling(out)
    assert all(not d.exists() for d in stale) and live.exists() and foreign.exists() and tmp.exists()
    assert clean_stale_siblings(out) == []


def test_a_killed_atomic_writes_temporary_file_is_cleaned_by_the_next_write(tmp_path):
    from aerorelay.store.outputs import write_atomic

    dead = _dead_pid()
    stale = tmp_path / f".manifest.json.tmp-{dead}-q1w2"
    stale.write_text("{half")
    write_atomic(tmp_path / "manifest.json", "{}")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["manifest.json"]


def test_a_writer_killed_mid_run_leaves_nothing_a_later_run_does_not_clean(tmp_path):
    out = tmp_path / "r"
    code = ("import sys, os, time; from aerorelay.store.outputs import new_sibling, writing\n"
            "with writing(sys.argv[1]):\n    t = new_sibling(__import__('pathlib').Path(sys.argv[1]))\n"
            "    (t / 'half').write_text('x'); print('ready', flush=True); time.sleep(60)\n")
    proc = subprocess.Popen([sys.executable, "-c", code, str(out)], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "ready"
    proc.kill()
    proc.wait()
    res = run_cli("run", NOMINAL, "--out", out, "--duration", "0.3", "--no-bound", "--no-figures")
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]


# ---------------------------------------------------------------- strict JSON
json_values = st.recursive(
    st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(), st.text(max_size=5), st.none(), st.booleans()),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(min_size=1, max_size=4), children, max_size=4),
    max_leaves=20)


def _refuse(token):
    raise ValueError(token)


@given(data=st.dictionaries(st.text(min_size=1, max_size=4), json_values, max_size=5))
def test_every_json_written_is_strict_and_says_why_a_value_is_null(data):
    text = strict_json.dumps(data)
    back = json.loads(text, parse_constant=_refuse)
    bad = _nonfinite_paths(data)
    assert set(back.get(strict_json.NULL_REASONS, {})) >= bad


def _nonfinite_paths(obj, path=""):
    out = set()
    if isinstance(obj, float) and not math.isfinite(obj):
        out.add(path or "value")
    elif isinstance(obj, dict):
        for k, v in obj.items():
            out |= _nonfinite_paths(v, f"{path}.{k}" if path else str(k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out |= _nonfinite_paths(v, f"{path}.{i}" if path else str(i))
    return out


# ---------------------------------------------------------------- the Python API's objects
bad_numbers = st.one_of(st.just(math.nan), st.just(math.inf), st.just(-math.inf), st.text(max_size=3), st.just(None),
                        st.just(True), st.lists(st.floats(), max_size=2))
bad_vectors = st.one_of(st.lists(st.floats(allow_nan=False, allow_infinity=False), max_size=2),
                        st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=4, max_size=5),
                        st.lists(st.floats(allow_infinity=True), min_size=3, max_size=3).filter(
                            lambda v: not all(math.isfinite(a) for a in v)),
                        st.text(max_size=4), st.just(None))


@given(power=st.one_of(bad_numbers, st.floats(max_value=-1e-12)))
def test_a_jammer_with_a_bad_power_is_named(power):
    with pytest.raises(InvalidInput, match=r"Jammer\('jammer'\)\.power: must be"):
        ar.Jammer(np.array([1.0, 2.0, 3.0]), power)


@given(position=bad_vectors)
def test_a_jammer_with_a_bad_position_is_named(position):
    with pytest.raises(InvalidInput, match=r"Jammer\('jam'\)\.position: must be 3 finite numbers"):
        ar.Jammer(position, 1.0, name="jam")


@pytest.mark.parametrize("make,needle", [
    (lambda: ar.Jammer([0, 0, 1], 1.0, localization_delay=-1), "localization_delay"),
    (lambda: ar.Jammer([0, 0, 1], 1.0, boresight=[0, 0, 0]), "boresight"),
    (lambda: ar.Jammer([0, 0, 1], 1.0, name=""), "Jammer.name"),
    (lambda: ar.Jammer([0, 0, 1], 1.0, pattern="dipole"), "pattern"),
    (lambda: ar.PeriodicOnOff(0.0, 5.0), "on_s"),
    (lambda: ar.Antenna(ar.DipolePattern(), np.array([0.0, 0.0, 2.0])), "Antenna.axis"),
    (lambda: ar.Antenna(None), "Antenna.pattern"),
    (lambda: ar.Node("r", "drone", ar.Antenna(ar.DipolePattern())), "role"),
    (lambda: ar.Node("bs", "base_station", ar.Antenna(ar.DipolePattern()), [0, 0, math.nan]), "position"),
    (lambda: ar.LinkBudget(noise_power=0.0), "noise_power"),
    (lambda: ar.LinkBudget(tx_power=-1.0), "tx_power"),
    (lambda: ar.RadioScene((ar.Node("bs", "base_station", ar.Antenna(ar.DipolePattern()), [0, 0, 0]),), jammers=("j",)),
     "RadioScene.jammers"),
])
def test_api_objects_name_the_object_and_field(make, needle):
    with pytest.raises(InvalidInput, match=needle.replace(".", r"\.")):
        make()


class _Planner:
    def __init__(self, make):
        self.make = make

    def update(self, inp):
        return self.make(inp)


def _holding_with(field, value):
    """A planner's step: a reference holding the relay, with ``field`` set to ``value``."""
    def make(inp):
        ref = dict(p_opt=inp.p1, p_ref=inp.p1, v_ref=np.zeros(3), a_ref=np.zeros(3))
        ref[field] = value
        return ar.Reference(**ref)
    return make


@pytest.mark.parametrize("field,value", [("p_ref", np.zeros(2)), ("a_ref", "up"), ("axis", np.ones(4))])
def test_a_planners_bad_reference_is_named(field, value):
    make = _holding_with(field, value)
    sc = load_scenario(NOMINAL, set={"sim.duration_s": 0.3})
    with pytest.raises(PlannerFailed, match=rf"planner '_Planner \(passed from Python\)' at t = 0\.000 s: relay 'relay': "
                                            rf"Reference.{field}: must be 3 numbers"):
        ar.simulate(sc, planner=_Planner(make))


@pytest.mark.parametrize("field,value", [("v_ref", np.full(3, np.nan)), ("axis", np.zeros(3))])
def test_a_planners_non_finite_reference_holds_the_relay_counted(field, value):
    """Issue 61: a reference that cannot be flown (non-finite, a zero axis) holds the relay where it is, counted."""
    make = _holding_with(field, value)
    sc = load_scenario(NOMINAL, set={"sim.duration_s": 0.3})
    res = ar.simulate(sc, planner=_Planner(make))
    assert res.metrics["reference_held_steps"] == res.metrics["steps"] and not res.metrics["unsafe"]
    assert "non-finite reference" in res.metrics["reference_first"]["relay"]


def test_a_reference_outside_the_workspace_is_clipped_and_counted():
    def make(inp):
        far = inp.p1 + np.array([0.0, 0.0, 100.0])
        return ar.Reference(p_opt=far, p_ref=far, v_ref=np.zeros(3), a_ref=np.zeros(3))
    sc = load_scenario(NOMINAL, set={"sim.duration_s": 0.3})
    res = ar.simulate(sc, planner=_Planner(make))
    assert res.metrics["reference_clipped_steps"] == res.metrics["steps"]
    assert "outside the workspace" in res.metrics["reference_first"]["relay"]
    assert res.timeseries["relay.pd_z"].max() <= sc.controller.workspace.max[2]


@pytest.mark.parametrize("change", [("nodes", "relay", [20.0, 0.0, 5.0], r"nodes\.relay \[20\.0, 0\.0, 5\.0\] must lie inside controller\.workspace"),
                                    ("controller.workspace", "min", [-7.0, -6.0, -2.0], r"controller\.workspace\.min: z = -2 m is below the ground")])
def test_a_scenario_changed_after_loading_is_validated_again(change):
    sc = load_scenario(NOMINAL, set={"sim.duration_s": 0.3})
    owner, field, value, named = change
    obj = sc
    for part in owner.split("."):
        obj = getattr(obj, part)
    setattr(obj, field, value)  # passes the field's own check, not the scenario's
    with pytest.raises(ScenarioError, match=named):
        ar.simulate(sc)
