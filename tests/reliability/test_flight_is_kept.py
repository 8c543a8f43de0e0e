"""Nothing computed after a flight can lose it: undefined ratios are null with a reason, optional
outputs that fail are named and the run stays, every check that can be made before flying is."""

import json
import math
import os
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from typer.testing import CliRunner

import aerorelay as ar
from aerorelay.assembly import load_scenario
from aerorelay.assembly.vehicle import build_vehicle
from aerorelay.cli import EXIT_BAD_INPUT, EXIT_UNSAFE, app
from aerorelay.config import ScenarioError
from aerorelay.experiments.run import efficiency, output_bytes, run_metrics
from aerorelay.store import run_folder
from aerorelay.store.outputs import OutputError, check_output_folder

ROOT = Path(__file__).resolve().parents[2]
NOMINAL = ROOT / "scenarios" / "nominal_tilted.toml"
runner = CliRunner()


def run_cli(*args):
    return runner.invoke(app, [str(a) for a in args])


def strict_load(path: Path):
    def refuse(token):
        raise ValueError(f"non-standard JSON constant {token}")
    return json.loads(Path(path).read_text(), parse_constant=refuse)


# ---------------------------------------------------------------- ratios that cannot be formed
@given(value=st.floats(allow_nan=True, allow_infinity=True),
       best=st.one_of(st.floats(max_value=0.0), st.just(math.nan), st.just(math.inf), st.just(-math.inf)))
def test_an_undefined_efficiency_is_null_with_its_reason(value, best):
    ratio, why = efficiency(value, best, "the best minimum")
    assert ratio is None and "undefined" in why and "the best minimum" in why


@given(value=st.floats(min_value=0.0, max_value=1e3), best=st.floats(min_value=1e-12, max_value=1e3))
def test_a_defined_efficiency_is_the_ratio(value, best):
    ratio, why = efficiency(value, best, "x")
    assert why is None and ratio == value / best


@pytest.fixture(scope="module")
def flown():
    sc = load_scenario(NOMINAL, set={"sim.duration_s": 0.3})
    return sc, ar.simulate(sc)


@pytest.mark.parametrize("zero", ["path_maxmin", "path_mean", "flyable_maxmin", "flyable_mean"])
@pytest.mark.parametrize("value", [0.0, -1e-3, np.nan])
def test_metrics_survive_a_bound_whose_best_is_zero_or_undefined(flown, zero, value):
    sc, res = flown
    arrays = {k: np.full(3, 2e-3) for k in ("path_maxmin", "path_mean", "flyable_maxmin", "flyable_mean")}
    arrays[zero] = np.full(3, value)
    bound = SimpleNamespace(**arrays, static=np.full(3, 3e-3), summary=lambda: {"static": {"min": value}})
    m = run_metrics(sc, res.mission, {"relay": build_vehicle(sc.platform)}, bound)
    nulls = [k for k in m if k.startswith("capacity_efficiency") and m[k] is None]
    assert len(nulls) == 1 and nulls[0] in m["null_reasons"]
    named = "efficiency_" + ("min" if "maxmin" in zero else "mean") + "_vs_" + zero.split("_")[0]  # the same ratio, named
    assert m[named] is None and named in m["null_reasons"]
    text = run_folder.strict_json.dumps(m)
    assert "NaN" not in text and "Infinity" not in text


# ---------------------------------------------------------------- optional outputs that fail
@pytest.mark.parametrize("exc", [OSError(28, "No space left on device"), RuntimeError("figure backend died"),
                                 MemoryError()])
def test_a_failing_optional_output_keeps_the_run(tmp_path, monkeypatch, exc):
    def broken(*args, **kwargs):
        raise exc
    monkeypatch.setattr("aerorelay.api.write_run_figures", broken)
    res = run_cli("run", NOMINAL, "--out", tmp_path / "r", "--duration", "0.3", "--no-bound")
    assert res.exit_code == 0, res.output
    m = strict_load(tmp_path / "r" / "metrics.json")
    assert "figures" in m["optional_outputs_failed"] and "not written" in res.output
    for f in ("scenario.toml", "timeseries.parquet"):
        assert (tmp_path / "r" / f).stat().st_size > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]  # no temporary folder left


def test_the_bound_files_failing_keep_the_run(tmp_path, flown):
    sc, res = flown
    res = type(res)(res.scenario, res.mission, res.timeseries, dict(res.metrics), res.bound)
    res.bound = SimpleNamespace(frame=lambda: (_ for _ in ()).throw(OSError(28, "No space left on device")),
                                summary=lambda: {})
    res.save(tmp_path / "r", figures=False)
    m = strict_load(tmp_path / "r" / "metrics.json")
    assert "No space left" in m["optional_outputs_failed"]["bound"]
    assert not (tmp_path / "r" / "bound.json").exists()


# ---------------------------------------------------------------- checks made before flying
@pytest.mark.parametrize("depth", [1, 2, 3])
def test_out_below_a_file_is_refused_before_flying(tmp_path, depth):
    f = tmp_path / "afile"
    f.write_text("x")
    out = f.joinpath(*["sub"] * depth)
    res = run_cli("run", NOMINAL, "--out", out, "--duration", "0.3", "--no-bound")
    assert res.exit_code == EXIT_BAD_INPUT and "is a file" in res.output and f.read_text() == "x"


def test_the_space_check_counts_the_copied_mission_file(tmp_path, monkeypatch):
    csv = tmp_path / "m.csv"
    t = np.linspace(0.0, 2.0, 20000)
    rows = np.column_stack([t, -3.04 + 0 * t, 5.79 + 0 * t, 1.72 + t] + [0 * t] * 6)
    np.savetxt(csv, rows, delimiter=",", header="t,px,py,pz,vx,vy,vz,ax,ay,az", comments="")
    sc = load_scenario(NOMINAL, set={"mission.trajectory_csv": str(csv)})
    need = output_bytes(sc, figures=False)
    assert need >= csv.stat().st_size + output_bytes(load_scenario(NOMINAL, set={"sim.duration_s": sc.duration_s}),
                                                     figures=False)
    usage = SimpleNamespace(total=10**12, used=0, free=need - 1)
    monkeypatch.setattr("aerorelay.store.outputs.shutil.disk_usage", lambda p: usage)
    with pytest.raises(OutputError, match="MB free"):
        check_output_folder(tmp_path / "out", "run", need_bytes=need)


@pytest.mark.parametrize("boresight", [[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]])
def test_an_inr_jammer_in_a_null_is_a_named_error_at_load(tmp_path, boresight):
    """A directional jammer with no back lobe pointing away from the relay's start: its power cannot
    be set from an interference-to-noise ratio; validate, info and run say so by field, exit 2."""
    relay = np.array([-6.95, 5.79, 1.72])
    jam = relay + 4.0 * np.array(boresight)  # the relay sits straight behind the jammer, which points away
    sets = ["jammer.pattern=\"cosine\"", "jammer.exponent=2.0", f"jammer.boresight={boresight}",
            f"jammer.position={jam.tolist()}", "jammer.inr_db_at_relay_start=10.0"]
    with pytest.raises(ScenarioError, match=r"jammer\.inr_db_at_relay_start: .*null"):
        load_scenario(NOMINAL, set=sets)
    for cmd in (["validate"], ["info"], ["run", "--out", tmp_path / "r", "--no-bound"]):
        res = run_cli(*cmd[:1], NOMINAL, *cmd[1:], *[a for s in sets for a in ("--set", s)])
        assert res.exit_code == EXIT_BAD_INPUT and "inr_db_at_relay_start" in res.output and "Traceback" not in res.output
    assert not (tmp_path / "r").exists()


def test_a_diverging_plant_keeps_the_steps_flown_and_is_unsafe(tmp_path, monkeypatch):
    """A plant state that turns non-finite mid-flight ends the flight: the steps flown are written,
    the run is unsafe (exit 3), never lost to an exception."""
    from aerorelay.sim import closed_loop

    real = closed_loop.plant_step_function

    def diverging(*args, **kwargs):
        f, calls = real(*args, **kwargs), [0]

        def step(x, u, d):
            calls[0] += 1
            return f(x, u, d) if calls[0] < 7 else np.full(np.size(x), np.nan)
        return step
    monkeypatch.setattr("aerorelay.assembly.parts.plant_step_function", diverging)
    res = run_cli("run", NOMINAL, "--out", tmp_path / "r", "--duration", "0.3", "--no-bound", "--no-figures")
    assert res.exit_code == EXIT_UNSAFE, res.output
    m = strict_load(tmp_path / "r" / "metrics.json")
    assert m["unsafe"] and "non-finite" in m["unsafe_reason"] and m["steps"] == 7
    assert m["exit_status"] == "non_finite" and m["exit_sentence"].startswith("a state stopped being finite")


def test_run_folders_follow_the_umask(tmp_path):
    for mask in (0o022, 0o027, 0o002):
        old = os.umask(mask)
        try:
            out = tmp_path / f"r{mask:o}"
            res = run_cli("run", NOMINAL, "--out", out, "--duration", "0.3", "--no-bound", "--no-figures")
        finally:
            os.umask(old)
        assert res.exit_code == 0, res.output
        assert out.stat().st_mode & 0o777 == 0o777 & ~mask
        assert (out / "metrics.json").stat().st_mode & 0o777 == 0o666 & ~mask


def test_metrics_that_fail_after_the_flight_keep_it_unsafe(tmp_path, monkeypatch):
    """A metric with no unit (as the ray-traced channel's delay spread once had) or a metric that raises: the
    flight's time series is kept and written, the run unsafe with why, never lost."""
    from aerorelay.experiments import run as run_module

    def no_unit(metrics, unit):
        raise KeyError("metric 'new_thing' has no unit: add it to sim/units.py")

    monkeypatch.setattr(run_module, "metric_units", no_unit)
    sc = load_scenario(NOMINAL).with_updates({"sim.duration_s": 0.3})
    result = ar.simulate(sc)
    assert result.metrics["unsafe"] and "new_thing" in result.metrics["metrics_failed"]
    assert len(result.timeseries) == len(result.mission.log["t"]) > 0
    result.save(tmp_path / "run")
    assert (tmp_path / "run" / "timeseries.parquet").is_file()
