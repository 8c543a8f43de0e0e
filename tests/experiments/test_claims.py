"""Claims declared as data in the study files, judged on the group metrics."""

import pytest

from aerorelay.experiments.study import Claim, Study, StudyError, load_study
from aerorelay.report.summary import evaluate_claim


def _study(**kw):
    base = dict(name="s", title="t", base="scenarios/nominal_tilted.toml",
                runs=[{"id": "a"}, {"id": "b"}], claims=[{"text": "a beats b", "all": [
                    {"left": "c_min@a", "op": ">=", "right": "c_min@b", "factor": 10.0}]}])
    base.update(kw)
    return Study.model_validate(base)


def test_claim_holds_and_fails_on_the_numbers():
    claim = _study().claims[0]
    holds, evidence = evaluate_claim(claim, {"a": {"c_min": 1e-3}, "b": {"c_min": 1e-5}})
    assert holds is True and "c_min@a = 0.001 >= 10 x c_min@b = 1e-05: yes" in evidence
    holds, _ = evaluate_claim(claim, {"a": {"c_min": 1e-3}, "b": {"c_min": 1e-3}})
    assert holds is False


def test_claim_with_a_missing_run_is_not_evaluated():
    holds, evidence = evaluate_claim(_study().claims[0], {"a": {"c_min": 1e-3}})
    assert holds is None and "c_min@b not run" in evidence


def test_ratio_terms_and_numeric_bounds():
    claim = Claim.model_validate({"text": "x", "all": [
        {"left": "c_mean@a / c_mean@b", "op": ">=", "value": 2.0},
        {"left": "d@a", "op": "<=", "value": 0.05}]})
    assert evaluate_claim(claim, {"a": {"c_mean": 3.0, "d": 0.01}, "b": {"c_mean": 1.0}})[0] is True
    assert evaluate_claim(claim, {"a": {"c_mean": 1.5, "d": 0.01}, "b": {"c_mean": 1.0}})[0] is False


def test_renaming_a_run_cannot_drop_a_claim_silently():
    with pytest.raises(ValueError, match="unknown runs.*claim 'a beats b': run 'b'"):
        _study(runs=[{"id": "a"}, {"id": "b_renamed"}])


@pytest.mark.parametrize("cond", [{"left": "c_min", "op": ">", "value": 1.0},
                                  {"left": "c_min@a", "op": ">", "value": 1.0, "right": "c_min@b"},
                                  {"left": "c_min@a", "op": "=>", "value": 1.0}])
def test_bad_conditions_are_rejected(cond):
    with pytest.raises(ValueError):
        Claim.model_validate({"text": "x", "all": [cond]})


def test_a_study_file_with_a_dangling_claim_is_a_study_error(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text('name = "s"\ntitle = "t"\nbase = "x.toml"\n[[runs]]\nid = "a"\n'
                 '[[claims]]\ntext = "c"\nall = [{ left = "c_min@gone", op = ">", value = 0.0 }]\n')
    with pytest.raises(StudyError, match="gone"):
        load_study(f)


def test_a_study_with_bound_records_the_efficiency_and_draws_the_bound(tmp_path):
    import json
    from pathlib import Path

    from aerorelay.experiments.campaign import execute_run, is_finished, run_dir
    from aerorelay.experiments.study import expand
    from aerorelay.report.html import render_report
    from aerorelay.report.summary import summarize

    root = Path(__file__).resolve().parents[2]
    study = Study.model_validate({
        "name": "b", "title": "bound", "base": "scenarios/nominal_tilted.toml", "bound": True,
        "bound_figures": [["paper", "capacity"]],
        "runs": [{"id": "paper", "set": {"sim.duration_s": 1.0, "bound.grid_m": 1.0}},
                 {"id": "capacity", "set": {"sim.duration_s": 1.0, "bound.grid_m": 1.0, "controller.planner": "capacity"}}],
        "claims": [{"text": "capacity at least as good", "all": [
            {"left": "capacity_efficiency_mean@capacity", "op": ">=", "right": "capacity_efficiency_mean@paper", "factor": 0.5}]}]})
    specs = expand(study, root)
    assert all(s.bound for s in specs)
    for s in specs:
        assert not is_finished(tmp_path, s)
        rec = execute_run(s, str(tmp_path))
        assert rec["status"] == "done", rec.get("error")
        assert is_finished(tmp_path, s)
        m = json.loads((run_dir(tmp_path, s) / "metrics.json").read_text())
        # the definition, from the run folder: C's mean over the bound's best-mean path's mean
        import pandas as pd

        path_mean = pd.read_parquet(run_dir(tmp_path, s) / "bound.parquet")["path_mean"].mean()
        assert m["capacity_efficiency_mean"] == pytest.approx(m["c_mean"] / path_mean, rel=1e-12)
        assert 0 < m["capacity_efficiency_mean"] <= 1.01  # a bound: within the grid's 1% tolerance (tests/planning/test_bound.py)
    summary = summarize([study], specs, tmp_path)
    assert summary["claims"][0]["holds"] is True
    page = render_report(summary, [study], specs, tmp_path, {})
    assert "paper vs capacity vs the bound" in page and "capacity_efficiency_mean" in page


def test_combinations_are_ranked_by_their_distance_to_the_paper():
    from aerorelay.report.summary import rank_against_paper

    study = Study.model_validate({
        "name": "a", "title": "t", "base": "x.toml", "grid": {"antenna.directivity": [1.0, 1.64], "controller.variant": ["c", "u"]},
        "ranking": {"pair_key": "controller.variant", "terms": [
            {"metric": "c_min", "at": "c", "paper": 1e-2}, {"metric": "c_min", "at": "c", "over": "u", "paper": 100.0},
            {"metric": "slack", "at": "c", "paper": 0.3, "scale": "abs"}]}})
    groups = {"directivity=1.0,variant=c": {"c_min": 1e-3, "slack": 0.8}, "directivity=1.0,variant=u": {"c_min": 1e-4},
              "directivity=1.64,variant=c": {"c_min": 1e-2, "slack": 0.3}, "directivity=1.64,variant=u": {"c_min": 1e-4}}
    ranking = rank_against_paper(study, groups)
    assert [r["combination"] for r in ranking] == ["directivity=1.64", "directivity=1.0"]
    assert ranking[0]["distance"] == pytest.approx(0.0)
    # log10(0.1) = -1, log10(10 / 100) = -1, 0.8 - 0.3 = 0.5: RMS = sqrt((1 + 1 + 0.25) / 3)
    assert ranking[1]["distance"] == pytest.approx(((1 + 1 + 0.25) / 3) ** 0.5)
    with pytest.raises(ValueError, match="pair_key"):
        Study.model_validate({"name": "a", "title": "t", "base": "x.toml", "grid": {"a.b": [1]},
                              "ranking": {"pair_key": "c.d", "terms": [{"metric": "m", "at": "x", "paper": 1.0}]}})


def test_measured_causes_are_computed_from_the_runs(tmp_path):
    """jammer_noise and fading read a finished run; their numbers match independent arithmetic."""
    import re
    from pathlib import Path

    import numpy as np

    from aerorelay.experiments.campaign import execute_run
    from aerorelay.experiments.study import Explanation, expand
    from aerorelay.report.explain import explain

    root = Path(__file__).resolve().parents[2]
    study = Study.model_validate({"name": "w", "title": "t", "base": "scenarios/nominal_tilted.toml",
                                  "runs": [{"id": "r", "set": {"sim.duration_s": 0.5}}]})
    specs = expand(study, root)
    assert execute_run(specs[0], str(tmp_path))["status"] == "done"
    text = explain(Explanation(kind="jammer_noise", run="r"), specs, tmp_path)
    d = np.array([-6.95, -5.79, 1.72])
    c = d[2] / np.linalg.norm(d)
    g = (np.cos(np.pi / 2 * c) / np.sqrt(1 - c * c)) ** 2  # the BS's vertical dipole toward the jammer
    assert f"add {g / (d @ d):.1%} to the BS's noise" in text
    text = explain(Explanation(kind="fading", run="r", k_db=[6.0]), specs, tmp_path)
    change = float(re.search(r"K = 6 dB: ([+-][0-9.]+)%", text).group(1))
    assert -15.0 < change < 0.0  # Jensen: fading can only lower a concave mean, and not by much at low SNR
    assert "has no results" in explain(Explanation(kind="fading", run="gone", k_db=[6.0]), specs, tmp_path)


def test_efficiency_keys_name_their_denominator_for_one_relay_and_for_a_fleet():
    """Issue 46: ``capacity_efficiency_mean`` is C over the path bound for one relay and over the static
    bound for a fleet; ``efficiency_<stat>_vs_<bound>`` names its denominator for every fleet size,
    recomputed here from the bound's own arrays."""
    import aerorelay as ar

    one = ar.simulate(ar.load_scenario("scenarios/nominal_tilted.toml", set={"sim.duration_s": 1.0, "bound.grid_m": 1.0}),
                      bound=True)
    m, b = one.metrics, one.bound
    assert m["efficiency_mean_vs_path"] == pytest.approx(m["c_mean"] / b.path_mean.mean(), rel=1e-12)
    assert m["efficiency_min_vs_path"] == pytest.approx(m["c_min"] / b.path_maxmin.min(), rel=1e-12)
    assert m["efficiency_mean_vs_static"] == pytest.approx(m["c_mean"] / b.static.mean(), rel=1e-12)
    assert m["efficiency_mean_vs_flyable"] == pytest.approx(m["c_mean"] / b.flyable_mean.mean(), rel=1e-12)
    assert m["capacity_efficiency_mean"] == m["efficiency_mean_vs_path"] and m["units"]["efficiency_mean_vs_path"] == "1"
    fleet = ar.simulate(ar.load_scenario("scenarios/chain_two_relays.toml", set={"sim.duration_s": 1.0}), bound=True)
    f, nb = fleet.metrics, fleet.bound
    assert f["efficiency_mean_vs_static"] == pytest.approx(f["c_mean"] / nb.static.mean(), rel=1e-12)
    assert f["efficiency_min_vs_achieved"] == pytest.approx(f["c_min"] / nb.achieved.min(), rel=1e-12)
    assert f["capacity_efficiency_mean"] == f["efficiency_mean_vs_static"]
    # a fleet's upper path bound (issue 47): its mean only (no max-min path bound for a fleet)
    assert f["efficiency_mean_vs_path"] == pytest.approx(f["c_mean"] / nb.path_mean.mean(), rel=1e-12)
    assert f["capacity_efficiency_mean_path"] == f["efficiency_mean_vs_path"] and "efficiency_min_vs_path" not in f
