"""One machinery (issue 46): every run, one relay or a fleet, flies the one closed loop
(``sim.closed_loop.ClosedLoop``). Its flights are compared column by column (1e-9 relative) with recorded logs
(``tests/data/record_before_one_machinery.py``), the one-relay cases under the old names read through
``sim.log_schema.modern_columns``: the nominal preset with the paper's planner and with the capacity planner, with
fading, CSI and process noise and gusty wind, with an estimated jammer, a chain of two relays and two sources sharing
it. **They are golden masters, not a second implementation**: recorded first by the two loops before issue 46
(05e1bca), every case was recorded again by the one loop when a deliberate change moved its flights, last on
2026-12-07 (issue 76: the bounded separation row; relay positions moved by at most 7 mm in these seconds, capacities
by 4.9e-4 relative). They guard the loop against an unintended change, on CPUs whose floating-point paths the test
command pins (``make test``: OpenBLAS's Haswell kernels, numpy without AVX-512)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import aerorelay as ar
from aerorelay.sim.log_schema import LEGACY_COLUMNS, modern_columns

DATA = Path(__file__).parents[1] / "data"
sys.path.insert(0, str(DATA))
from record_before_one_machinery import CASES  # noqa: E402

TIMINGS = ("solve_ms", "feedback_ms", "estimator_ms")  # wall-clock measurements: the only columns a flight may change


@pytest.mark.parametrize("case", list(CASES))
def test_the_one_loop_flies_its_recorded_flights(case):
    path, updates = CASES[case]
    before = pd.read_parquet(DATA / "before_one_machinery" / f"{case}.parquet")
    before = before.rename(columns=modern_columns(before.columns))
    now = ar.simulate(ar.load_scenario(path, set=updates)).timeseries
    assert len(now) == len(before)
    assert not set(before.columns) - set(now.columns), "a column the old log had is gone"
    for c in before.columns:
        if c.endswith(TIMINGS):
            continue
        old, new = before[c].to_numpy(), now[c].to_numpy()
        if old.dtype.kind == "f":
            np.testing.assert_allclose(new.astype(float), old, rtol=1e-9, atol=0.0, err_msg=c)
        else:
            assert (new == old).all(), c


def test_every_old_one_relay_column_has_its_new_name():
    """The migration table names a column of the one vocabulary for every old one-relay column."""
    old = pd.read_parquet(DATA / "before_one_machinery" / "nominal_paper.parquet").columns
    rename = modern_columns(old)
    kept = {"t", "capacity", "jammer_on"} | {c for c in old if c.startswith("jam_")}
    assert set(old) - set(rename) == kept
    assert len(set(rename.values())) == len(rename)  # no two old columns on one new name
    assert rename["p1_x"] == "relay.p_x" and rename["gamma_21"] == "sinr.source.relay" and rename["Omega_6"] == "relay.Omega_6"
    assert LEGACY_COLUMNS["v_12"] == "relay.v_up" and LEGACY_COLUMNS["v_10"] == "relay.v_down"


class TowardPoint:
    """A user's one-relay planner: the reference moves toward ``goal`` (m) at ``speed`` (m/s)."""

    def __init__(self, goal, speed=1.0):
        self.goal, self.speed, self.p_ref = np.asarray(goal, float), speed, None
        self.seen: list[np.ndarray] = []

    def update(self, inp: ar.PlannerInput) -> ar.Reference:
        self.seen.append(inp.p2.copy())
        if self.p_ref is None:
            self.p_ref = inp.p1.copy()
        step = self.goal - self.p_ref
        step *= min(1.0, self.speed * inp.dt / max(float(np.linalg.norm(step)), 1e-12))
        self.p_ref = self.p_ref + step
        return ar.Reference(p_opt=self.goal, p_ref=self.p_ref.copy(), v_ref=step / inp.dt, a_ref=np.zeros(3))


def test_a_users_one_relay_planner_flies_the_first_relay_of_a_chain_with_the_others_held():
    """Issue 46 (item 2): a one-relay planner passed to ``ar.simulate`` plans the chain's first relay (its
    source the route's upstream node, ``inspector``); the second relay's reference holds its start; the
    run names the part it was flown with."""
    sc = ar.load_scenario("scenarios/chain_two_relays.toml", set={"sim.duration_s": 2.0})
    r1, r2 = (np.array(r.start, float) for r in sc.relay_list)
    planner = TowardPoint(r1 + [0.0, 0.0, 1.0], speed=0.5)
    r = ar.simulate(sc, planner=planner)
    df = r.timeseries
    assert not r.metrics["unsafe"], r.metrics["unsafe_reason"]
    np.testing.assert_allclose(df[["r2.pd_x", "r2.pd_y", "r2.pd_z"]].to_numpy(), np.tile(r2, (len(df), 1)))
    assert df["r1.pd_z"].iloc[-1] == pytest.approx(r1[2] + 1.0)  # 1 m at 0.5 m/s: reached within 2 s
    assert df["r1.p_z"].iloc[-1] - r1[2] > 0.5  # and flown toward
    inspector = np.array([df[f"inspector.p_{a}"].iloc[0] for a in "xyz"])
    np.testing.assert_allclose(planner.seen[0], inspector)  # its MRAV-2 is the chain's source (no CSI noise here)
    assert r.metrics["injected"] == ["planner: TowardPoint"]


def test_a_registered_network_planner_is_named_from_the_scenario_file():
    """``controller.planner`` names any registered network planner (no list to edit); an unknown name is an
    error naming the field and the registered ones, before any work."""
    from aerorelay.config import ScenarioError
    from aerorelay.planning.base import PLANNERS, register_network_planner
    from aerorelay.planning.fleet import held_reference

    @register_network_planner("test_hold_all")
    def _hold_all(ctx):
        class HoldAll:
            def update(self, inp):
                return {name: held_reference(p) for name, p in ctx.starts.items()}
        return HoldAll()

    try:
        sc = ar.load_scenario("scenarios/chain_two_relays.toml", set={"sim.duration_s": 0.3, "controller.planner": "test_hold_all"})
        df = ar.simulate(sc).timeseries
        for r in sc.relay_list:
            np.testing.assert_allclose(df[[f"{r.name}.pd_{a}" for a in "xyz"]].to_numpy(), np.tile(r.start, (len(df), 1)))
    finally:
        PLANNERS.pop("test_hold_all")
    with pytest.raises(ScenarioError, match=r"controller.planner: no planner registered as 'nope'; registered: capacity, "
                                            r"equidistant, isotropic, single_shot, trajectory_generator"):
        ar.load_scenario("scenarios/chain_two_relays.toml", set={"controller.planner": "nope"})
    # a planner registered for one relay only is refused for a network, by name
    with pytest.raises(ScenarioError, match=r"controller.planner: .*'single_shot'.*one relay"):
        ar.load_scenario("scenarios/chain_two_relays.toml", set={"controller.planner": "single_shot"})


def test_a_run_folder_written_before_the_one_vocabulary_still_reports_and_exports(tmp_path):
    """A one-relay folder with the old column names (``p1_x``, ``gamma_21``...): ``report`` and ``export``
    read it under the new names (its route's capacity and the relay-to-source distance derived)."""
    from typer.testing import CliRunner

    from aerorelay.cli import app
    from aerorelay.report.folders import read_timeseries

    r = ar.simulate(ar.load_scenario("scenarios/nominal_tilted.toml", set={"sim.duration_s": 0.3}))
    run = r.save(tmp_path / "run", figures=False)
    now = pd.read_parquet(run / "timeseries.parquet")
    back = {new: old for old, new in modern_columns(pd.read_parquet(DATA / "before_one_machinery" / "nominal_paper.parquet")
                                                    .columns).items()}
    now.drop(columns=["capacity.source", "separation_min"]).rename(columns=back).to_parquet(run / "timeseries.parquet")
    assert "p1_x" in pd.read_parquet(run / "timeseries.parquet")
    df = read_timeseries(run)
    assert set(df.columns) == set(now.columns)
    np.testing.assert_array_equal(df["capacity.source"], now["capacity"])
    np.testing.assert_allclose(df["separation_min"], now["separation_min"], rtol=1e-12)
    for command in (["report", str(run)], ["export", str(run)]):
        res = CliRunner().invoke(app, command)
        assert res.exit_code == 0, res.output
    assert (run / "report.html").stat().st_size > 0 and (run / "run.mcap").stat().st_size > 0
