"""Units that never mislead: every metric carries its unit, the outage threshold follows the unit
system, values print with SI prefixes, runs of two unit systems are never divided."""

import json
import math
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from typer.testing import CliRunner

import aerorelay as ar
from aerorelay.assembly import load_scenario
from aerorelay.cli import EXIT_BAD_INPUT, app
from aerorelay.sim.units import metric_units, si

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()


@pytest.mark.parametrize("preset,sets,physical", [
    ("nominal_tilted", {}, False),
    ("moving_jammer", {"jammer.localization": "estimated"}, False),
    ("rma_av", {}, True),
])
def test_every_metric_carries_its_unit(preset, sets, physical):
    sc = load_scenario(ROOT / "scenarios" / f"{preset}.toml", set={"sim.duration_s": 0.5, **sets})
    m = ar.simulate(sc).metrics
    quantities = {k for k, v in m.items() if isinstance(v, int | float | dict | list) and not isinstance(v, bool)
                  and k not in ("units", "null_reasons", "optional_outputs_failed", "bound", "exit_statuses", "reference_first")}  # names
    groups = {"routes", "relays"}  # a table per route and per relay: each of their metrics has its unit, by its path
    assert quantities - groups <= set(m["units"]), quantities - groups - set(m["units"])
    for group in groups:
        for node, node_metrics in m[group].items():
            named = {f"{group}.{node}.{k}" for k, v in node_metrics.items() if isinstance(v, int | float | dict | list)
                     and not isinstance(v, bool) and k != "exit_statuses"}
            assert named <= set(m["units"]), named - set(m["units"])
    assert m["unit_system"] == ("physical" if physical else "normalized")
    assert m["units"]["c_min"] == ("bit/s" if physical else "bit/s/Hz") and m["units"]["se_21_mean"] == "bit/s/Hz"
    assert m["units"]["energy_kJ"] == "kJ" and m["units"]["solve_ms"] == "ms" and m["units"]["outage_fraction"] == "1"


def test_a_metric_without_a_unit_cannot_be_written():
    with pytest.raises(KeyError, match="no unit"):
        metric_units({"c_min": 1.0, "brand_new_metric": 2.0}, "bit/s/Hz")


@given(bandwidth=st.floats(min_value=1e3, max_value=1e10))
def test_the_physical_outage_threshold_is_the_papers_spectral_efficiency_times_the_bandwidth(bandwidth):
    sc = load_scenario(ROOT / "scenarios" / "nominal_tilted.toml")
    phys = sc.channel.model_copy(update={"units": "physical", "bandwidth_hz": bandwidth})
    assert phys.outage == pytest.approx(1e-3 * bandwidth)
    assert sc.channel.outage == 1e-3  # the paper's, normalized


def test_an_explicit_threshold_wins_and_the_resolved_one_is_recorded():
    sc = load_scenario(ROOT / "scenarios" / "nominal_tilted.toml", set={"channel.units": "physical", "channel.bandwidth_hz": 1e6,
                                                                        "sim.duration_s": 0.3})
    assert sc.channel.outage == 1000.0
    m = ar.simulate(sc).metrics
    assert m["outage_threshold"] == 1000.0 and m["units"]["outage_threshold"] == "bit/s"
    res = CliRunner().invoke(app, ["validate", str(ROOT / "scenarios" / "nominal_tilted.toml")])
    assert "outage_threshold (unset) resolves to 0.001 bit/s/Hz" in res.output
    sc2 = sc.with_updates({"channel.outage_threshold": 5e4})
    assert sc2.channel.outage == 5e4 and sc2.with_updates({"channel.units": "normalized"}).channel.outage == 5e4


@given(value=st.floats(min_value=1e-9, max_value=1e14), unit=st.sampled_from(["bit/s", "W", "Hz", "m", "s"]))
def test_si_prefixes_keep_the_mantissa_between_1_and_1000(value, unit):
    text = si(value, unit)
    number, prefixed = text.split(" ")
    prefix = prefixed[: len(prefixed) - len(unit)]
    scale = {"T": 1e12, "G": 1e9, "M": 1e6, "k": 1e3, "": 1.0, "m": 1e-3, "u": 1e-6, "n": 1e-9}[prefix]
    assert prefixed.endswith(unit)
    assert math.isclose(float(number) * scale, value, rel_tol=1e-3)
    if value >= 1e-9:
        assert 1.0 <= abs(float(number)) < 1000.5 or prefix == "n"


def test_compare_refuses_runs_in_two_unit_systems(tmp_path):
    for name, system in (("a", "normalized"), ("b", "physical")):
        d = tmp_path / name
        d.mkdir()
        (d / "metrics.json").write_text(json.dumps({"c_min": 1e-3 if system == "normalized" else 2e5, "unit_system": system}))
    res = runner.invoke(app, ["compare", str(tmp_path / "a"), str(tmp_path / "b")])
    assert res.exit_code == EXIT_BAD_INPUT and "normalized units" in res.output and "physical" in res.output
    assert "ratio" not in res.output.split("error")[0]
