"""Outputs keep their shape with the count (issue 78): every relay metric reaches the network's top level by one
rule, the same keys for one relay and for K; each rule checked here from its definition."""

import ast
import inspect
import math

import numpy as np
import pytest

from aerorelay.sim import metrics as M

A = {"fallback_fraction": 0.02, "alignment_ok_fraction": 0.9, "distance_m": 10.0, "safety_violations": 1,
     "omega_range_hz": [20.0, 90.0], "solve_ms": {"mean": 1.0, "p99": 5.0}, "max_tilt_deg": math.nan,
     "final_z_m": 4.0, "unsafe": False, "took_over_at_s": 3.0}
B = {"fallback_fraction": 0.30, "alignment_ok_fraction": 0.5, "distance_m": 2.5, "safety_violations": 2,
     "omega_range_hz": [30.0, 95.0], "solve_ms": {"mean": 2.0, "p99": 3.0}, "max_tilt_deg": 12.0,
     "final_z_m": 6.0, "unsafe": True}


def test_the_fleet_reads_the_worst_relay_the_sum_the_envelope_and_the_slowest():
    out = M.fleet_metrics({"a": A, "b": B})
    assert out["fallback_fraction"] == 0.30  # the worst share of brake-law steps
    assert out["alignment_ok_fraction"] == 0.5  # the worst share of aligned steps
    assert out["final_z_m"] == 4.0  # the lowest
    assert out["distance_m"] == 12.5 and out["safety_violations"] == 3 and isinstance(out["safety_violations"], int)
    assert out["omega_range_hz"] == [20.0, 95.0]
    assert out["solve_ms"] == {"mean": 2.0, "p99": 3.0}  # one relay's stats (the slowest mean), not a mix
    assert out["max_tilt_deg"] == 12.0  # a NaN skipped
    assert "unsafe" not in out and "took_over_at_s" not in out  # the verdict's and a spare's event stay per relay


def test_one_relay_reads_as_itself():
    out = M.fleet_metrics({"r": A})
    for k, v in out.items():
        assert v == A[k] or (isinstance(v, float) and math.isnan(v) and math.isnan(A[k])), k
    assert set(out) == set(A) - {"unsafe", "took_over_at_s"}
    assert M.fleet_metrics({"spare": {"flew": False}, "r": A}) == out  # a spare that never flew counts for nothing


def _written_keys(fn) -> set[str]:
    """The string keys a metrics function writes: dict literals' keys and ``out[...] =`` targets."""
    keys = set()
    for node in ast.walk(ast.parse(inspect.getsource(fn))):
        if isinstance(node, ast.Dict):
            keys |= {k.value for k in node.keys if isinstance(k, ast.Constant) and isinstance(k.value, str)}
        if isinstance(node, ast.Subscript) and isinstance(node.ctx, ast.Store) and isinstance(node.slice, ast.Constant):
            keys.add(node.slice.value)
    return keys


@pytest.mark.parametrize("fn", [M.relay_metrics, M.safety_metrics, M.air_metrics, M.saturation_metrics, M.battery_metrics,
                                M.spare_metrics])
def test_every_metric_a_relay_writes_has_a_fleet_rule(fn):
    ruled = {*M.FLEET_MIN, *M.FLEET_MAX, *M.FLEET_SUM, *M.FLEET_ENVELOPE, *M.FLEET_SLOWEST, *M.PER_RELAY}
    written = _written_keys(fn) - {"mean", "std"}  # a stats dict's own fields
    assert written - ruled == set(), f"{fn.__name__} writes {sorted(written - ruled)} with no fleet rule"
    rules = [M.FLEET_MIN, M.FLEET_MAX, M.FLEET_SUM, M.FLEET_ENVELOPE, M.FLEET_SLOWEST, M.PER_RELAY]
    assert sum(len(r) for r in rules) == len(ruled), "a metric with two rules"


def test_a_network_run_has_the_one_relay_keys_at_the_top(tmp_path):
    import aerorelay as ar

    one = ar.simulate(ar.load_scenario("scenarios/nominal_tilted.toml", set={"sim.duration_s": 0.5})).metrics
    chain = ar.simulate(ar.load_scenario("scenarios/chain_two_relays.toml", set={"sim.duration_s": 0.5})).metrics
    relay_keys = set(next(iter(one["relays"].values()))) - set(M.PER_RELAY)
    assert relay_keys <= set(one) and relay_keys <= set(chain)
    r1, r2 = (chain["relays"][r] for r in chain["relays"])
    assert chain["max_tilt_deg"] == max(r1["max_tilt_deg"], r2["max_tilt_deg"])
    assert chain["energy_kJ"] == pytest.approx(r1["energy_kJ"] + r2["energy_kJ"], rel=1e-12)
    assert np.isfinite(chain["position_error_mean_m"])
