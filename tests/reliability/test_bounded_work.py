"""Bounded work (issue 45, item 4): a named error naming what to change, before any work, for bounds
that would not fit the machine or the time allowed, obstacle checks of long missions, huge or empty
campaigns and special files; plus the wrong errors and silent acceptances the battery found. Before:
a K = 4 network bound over a 200 m box ran 300 s at 2.4 GB with nothing printed (``run`` hung in it
before flying); the finest network grid and a 200 m one-relay bound ended in MemoryError; one obstacle
with a 1e7 s mission took 3 min 48 s and 5.5 GB to fail; a 1 cm wall between two samples let a mission
through it; a 216,000-run grid took over 300 s before any output; /dev/zero or a FIFO as the scenario
hung; an empty grid list or studies folder made an empty campaign with exit 0; ``--set seed=true`` gave
seed 1; ``sources = 5`` was a traceback; ``run --duration 3`` with a relay lost at 30 s was refused."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from typer.testing import CliRunner

import aerorelay as ar
from aerorelay.assembly import checks
from aerorelay.assembly.parts import check_bound_size
from aerorelay.cli import app
from aerorelay.config import ScenarioError
from aerorelay.experiments.study import MAX_RUNS, Study, StudyError, expand, find_studies
from aerorelay.models.obstacles import Box, VerticalCylinder, segment_clearance
from aerorelay.planning.bound import position_grid
from aerorelay.planning.bound_cost import BoundTooLarge, check_bound_cost, grid_cells, single_bound_cost

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()
NOMINAL = ROOT / "scenarios" / "nominal_tilted.toml"
CHAIN = ROOT / "scenarios" / "chain_two_relays.toml"
BIG_BOX = {"controller.workspace.min": [-100.0, -100.0, 0.5], "controller.workspace.max": [100.0, 100.0, 100.0]}


def test_the_grid_cell_count_is_the_bounds_own():
    lo, hi = np.array([-7.0, -6.0, 0.5]), np.array([7.0, 6.0, 19.0])
    for step in (0.5, 0.7, 2.0):
        assert grid_cells(lo, hi, step) == position_grid(lo, hi, step)[1].shape[0]


def test_a_one_relay_bound_over_a_200_m_box_is_refused_before_any_work():
    sc = ar.load_scenario(NOMINAL, set=BIG_BOX)
    t0 = time.perf_counter()
    with pytest.raises(BoundTooLarge, match=r"bound\.grid_m: the bound holds ~\d+ GB at once.* coarser fits"):
        ar.bound(sc)
    assert time.perf_counter() - t0 < 30.0  # refused, not computed (the bound itself needs ~150 GB)


@pytest.mark.parametrize("updates,field", [
    ({"relays": [{"name": f"r{i}", "start": [float(10 * i), 5.0, 5.0]} for i in range(1, 5)]} | BIG_BOX, "bound.grid_m"),
    ({"bound.grid_m": 0.25}, "bound.grid_m"),
])
def test_network_bounds_too_large_are_refused_naming_the_grid(updates, field):
    sc = ar.load_scenario(CHAIN, set={k: v for k, v in updates.items() if k != "relays"})
    if "relays" in updates:
        sc = sc.with_updates({"relays": updates["relays"], "network.routes": [["inspector", "r4", "r3", "r2", "r1", "bs"]]})
    with pytest.raises(BoundTooLarge, match=field.replace(".", r"\.") + r": the bound .*relay-relay hops"):
        check_bound_size(sc)


def test_the_presets_bounds_pass_the_guard():
    for f in ("nominal_tilted", "chain_two_relays", "two_sources", "long_inspection", "nominal_tower"):
        check_bound_size(ar.load_scenario(ROOT / "scenarios" / f"{f}.toml"))


def test_the_guard_takes_the_time_allowed_and_names_memory_first():
    cost = single_bound_cost([0, 0, 0], [10, 10, 10], 0.5, 0.5, 100.0, 60)
    check_bound_cost(cost, max_minutes=60, grid_field="bound.grid_m", dt_field="bound.dt_s", memory_bytes=2**40)
    with pytest.raises(BoundTooLarge, match="would take .* more than bound.max_minutes = 0.01"):
        check_bound_cost(cost, max_minutes=0.01, grid_field="bound.grid_m", dt_field="bound.dt_s", memory_bytes=2**40)
    with pytest.raises(BoundTooLarge, match="holds .* more than half of this machine's 0 GB"):
        check_bound_cost(cost, max_minutes=60, grid_field="bound.grid_m", dt_field="bound.dt_s", memory_bytes=1000)


def test_run_refuses_a_bound_too_large_before_flying_and_flies_with_no_bound(tmp_path):
    args = ["run", str(NOMINAL), "--duration", "0.1", "--no-figures"] + [a for k, v in BIG_BOX.items() for a in ("--set", f"{k}={v}")]
    r = runner.invoke(app, [*args, "--out", str(tmp_path / "a")])
    assert r.exit_code == 2 and "bound.grid_m: the bound holds" in " ".join(r.output.split())
    assert not (tmp_path / "a").exists()
    r = runner.invoke(app, [*args, "--out", str(tmp_path / "b"), "--no-bound"])
    assert r.exit_code == 0, r.output


# -- obstacle checks of missions ----------------------------------------------------------------------

def _with_slab(**more):
    """The nominal mission crosses z = 4 m near (-2.56, 5.32): a 1 cm slab there (between two 0.1 s samples,
    6 cm apart in z)."""
    slab = {"name": "slab", "kind": "box", "min_m": [-7.0, 5.0, 4.0], "max_m": [-2.0, 6.5, 4.01], "margin_m": 0.0}
    return ar.load_scenario(NOMINAL, set={"obstacles": [slab], **more})


def test_a_thin_wall_between_two_samples_is_found():
    with pytest.raises(ScenarioError, match="mission: the source's path goes through obstacle 'slab'"):
        _with_slab()


def test_a_long_mission_is_checked_in_bounded_samples(monkeypatch):
    """A mission of waypoints ends at its last one: a 1e7 s flight checks its 47 s path, not 1e8 samples."""
    calls = []
    real = checks.source_trajectory

    def counting(m):
        path = real(m)
        state = path.state
        path.state = lambda t: calls.append(t) or state(t)  # type: ignore[method-assign]
        return path
    monkeypatch.setattr(checks, "source_trajectory", counting)
    pole = {"name": "pole", "kind": "cylinder", "centre_m": [5.0, -5.0], "radius_m": 0.2, "z_min_m": 0.0, "z_max_m": 3.0}
    with pytest.raises(ScenarioError):  # its log would not fit: refused by the run's size check, after the bounded check
        sc = ar.load_scenario(NOMINAL, set={"obstacles": [pole], "sim.duration_s": 1e7})
        ar.api.check_run(sc, "/tmp/never-written", figures=False)
    assert 0 < len(calls) <= checks.MISSION_SAMPLES_MAX + 1


@given(lo=st.lists(st.floats(-5, 5), min_size=3, max_size=3), size=st.lists(st.floats(0.01, 4), min_size=3, max_size=3),
       a=st.lists(st.floats(-10, 10), min_size=3, max_size=3), b=st.lists(st.floats(-10, 10), min_size=3, max_size=3),
       cyl=st.booleans())
def test_segment_clearance_is_the_minimum_along_the_segment(lo, size, a, b, cyl):
    """Against brute force: never above the sampled minimum, and within the sampling's own error of it."""
    shape = (VerticalCylinder((lo[0], lo[1]), size[0], lo[2], lo[2] + size[2]) if cyl
             else Box(tuple(lo), tuple(np.add(lo, size))))
    a, b = np.array(a), np.array(b)
    s = np.linspace(0.0, 1.0, 20001)[:, None]
    brute = float(np.min(shape.signed_distance(a + s * (b - a))))
    exact = float(segment_clearance(shape, a[None], b[None])[0])
    assert exact <= brute + 1e-9
    assert exact >= brute - np.linalg.norm(b - a) / 20000 - 1e-9  # the samples are that far apart at most


# -- special files, campaigns, values -------------------------------------------------------------

def test_a_device_or_a_fifo_as_the_scenario_is_named(tmp_path):
    with pytest.raises(ScenarioError, match="not a regular file"):
        ar.load_scenario("/dev/zero")
    fifo = tmp_path / "scenario.toml"
    os.mkfifo(fifo)
    with pytest.raises(ScenarioError, match="not a regular file"):  # before: read forever
        ar.load_scenario(fifo)
    big = tmp_path / "big.toml"
    big.write_bytes(b"# " + b"x" * (5 * 2**20))
    with pytest.raises(ScenarioError, match="more than a scenario file holds"):
        ar.load_scenario(big)


def test_campaigns_that_make_no_runs_or_too_many_are_named(tmp_path):
    with pytest.raises(StudyError, match="no study files"):
        find_studies(tmp_path)
    base = {"name": "g", "title": "t", "base": str(NOMINAL)}
    with pytest.raises(ValueError, match=r"grid\.seed: an empty list makes no runs"):
        Study.model_validate(base | {"grid": {"seed": []}})
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match="make 216,000 runs, more than the 10,000"):
        Study.model_validate(base | {"grid": {"seed": list(range(60)), "controller.mu": [0.1] * 60, "sim.dt_s": [0.001] * 60}})
    assert time.perf_counter() - t0 < 5.0 and MAX_RUNS == 10_000
    r = runner.invoke(app, ["reproduce", "--studies-dir", str(tmp_path), "--out", str(tmp_path / "out")])
    assert r.exit_code == 2 and "no study files" in r.output


@pytest.mark.parametrize("sets,field", [(["seed=true"], "seed: Input should be a valid integer"),
                                        (["sim.duration_s=true"], "sim.duration_s")])
def test_booleans_are_not_numbers(sets, field):
    r = runner.invoke(app, ["validate", str(NOMINAL), *[a for s in sets for a in ("--set", s)]])
    assert r.exit_code == 2 and field in r.output


def test_a_wrongly_typed_table_is_named(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text("sources = 5\n")
    with pytest.raises(ScenarioError, match="sources: Input should be a valid list"):
        ar.load_scenario(f)


def test_quick_mode_names_a_loss_it_cuts_off():
    """Before: ``aerorelay reproduce network --quick`` was refused (its 30 s loss past the 12 s quick end)."""
    studies = {s.name: s for s in find_studies(ROOT / "experiments")}
    notices: list[str] = []
    specs = expand(studies["network"], ROOT, quick=True, notices=notices)
    assert specs and any("before its relay loss" in n and "flown without the loss" in n for n in notices)


def test_an_absurd_wind_is_named_before_flying(tmp_path):
    """Before: a 1e300 m/s wind flew, then its metrics raised and nothing was written."""
    r = runner.invoke(app, ["run", str(NOMINAL), "--duration", "0.3", "--no-bound", "--no-figures", "--set",
                            "wind.mean_m_s=[1e300, 0, 0]", "--out", str(tmp_path / "w")])
    assert r.exit_code == 2 and "wind.mean_m_s: |v| = 1e+300 m/s; allowed 0-40 m/s" in " ".join(r.output.split())


def test_metrics_that_fail_after_a_flight_keep_the_flight(tmp_path, monkeypatch):
    """Nothing computed after a flight may lose it: the time series is saved, the run unsafe (exit 3)."""
    import aerorelay.experiments.run as run

    def broken(*a, **k):
        raise ZeroDivisionError("a metric divided by zero")
    monkeypatch.setattr(run, "compute_metrics", broken)
    r = runner.invoke(app, ["run", str(NOMINAL), "--duration", "0.3", "--no-bound", "--no-figures", "--out", str(tmp_path / "k")])
    assert r.exit_code == 3 and "its metrics could not be computed (ZeroDivisionError" in " ".join(r.output.split())
    import pandas as pd

    assert len(pd.read_parquet(tmp_path / "k" / "timeseries.parquet")) == 21
