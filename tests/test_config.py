from pathlib import Path

import pytest

from aerorelay.assembly import load_scenario, parse_scenario
from aerorelay.assembly.parts import nmpc_settings, relay_pattern
from aerorelay.config import ScenarioError
from aerorelay.control.nmpc import NmpcSettings
from tests.rt_marks import MISSING, SKIP_RT

ROOT = Path(__file__).resolve().parents[1]
PRESETS = sorted((ROOT / "scenarios").glob("*.toml"))


@pytest.mark.parametrize("path", PRESETS, ids=lambda p: p.stem)
def test_presets_load_and_round_trip(path):
    if SKIP_RT and 'model = "ray_traced"' in path.read_text():
        pytest.skip(f"optional rt extra: {MISSING}")
    sc = load_scenario(path)
    import tomllib

    again = parse_scenario(tomllib.loads(sc.to_toml()))
    assert again == sc


def test_nominal_values_are_the_papers():
    sc = load_scenario(ROOT / "scenarios" / "nominal_tilted.toml")
    assert sc.platform.tilt_deg == 20.0 and sc.platform.mass_kg == 2.57
    assert sc.controller.ts_s == 0.015 and sc.controller.horizon == 30 and sc.controller.mu == 0.2
    assert sc.jammer.localization_delay_s == 2.0 and sc.duration_s == 47.0
    assert load_scenario(ROOT / "scenarios" / "nominal_coplanar.toml").platform.tilt_deg == 0.0


@pytest.mark.parametrize(
    "data,field,fragment",
    [
        ({"platform": {"mass_kg": -1.0}}, "platform.mass_kg", "(0, inf)"),
        ({"platform": {"omega_min_hz": 60.0, "omega_max_hz": 50.0}}, "platform", "must be <"),
        ({"controller": {"ts_s": 0.0}}, "controller.ts_s", "(0, 0.05]"),
        ({"controller": {"horizon": 0}}, "controller.horizon", "[1, 200]"),
        ({"controller": {"mu": 1.5}}, "controller.mu", "[0, 1]"),
        ({"perturbations": {"fading_k_db": -3.0}}, "perturbations.fading_k_db", "[0, inf)"),
        ({"nodes": {"relay": [0.0, 0.0, 0.05]}}, "scenario", "coincide"),
        ({"platform": {"omega_max_hz": 55.0}}, "platform", "hover infeasible"),
        ({"platform": {"wings": 2}}, "platform.wings", "unknown field"),
        ({"mission": {"waypoints": [[0, 0, 1, 1], [0, 1, 1, 1]]}}, "mission.waypoints", "increasing"),
        ({"sim": {"control_rate_hz": 300.0}}, "scenario", "whole number of plant steps"),
    ],
)
def test_bad_input_names_field_and_range(data, field, fragment):
    with pytest.raises(ScenarioError) as exc:
        parse_scenario(data)
    msg = str(exc.value)
    assert msg.startswith(field + ":") or f"\n{field}:" in msg
    assert fragment in msg


def test_with_updates_validates():
    sc = parse_scenario({})
    assert sc.with_updates({"controller.variant": "unconstrained"}).controller.variant == "unconstrained"
    with pytest.raises(ScenarioError, match="controller.mu"):
        sc.with_updates({"controller.mu": -0.1})


def test_missing_and_malformed_files(tmp_path):
    with pytest.raises(ScenarioError, match="no such scenario file"):
        load_scenario(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("this is = = not toml")
    with pytest.raises(ScenarioError, match="not valid TOML"):
        load_scenario(bad)


def test_trajectory_csv_resolved_next_to_the_scenario_and_checked(tmp_path):
    (tmp_path / "path.csv").write_text("t,px,py,pz,vx,vy,vz,ax,ay,az\n0,-3,5,2,0,0,0,0,0,0\n10,-3,5,4,0,0,0.2,0,0,0\n")
    f = tmp_path / "s.toml"
    f.write_text('[mission]\ntrajectory_csv = "path.csv"\n')
    sc = load_scenario(f)
    assert sc.mission.trajectory_csv == str((tmp_path / "path.csv").resolve())
    from aerorelay.models.mission import source_trajectory

    assert source_trajectory(sc.mission).state(5.0).p[2] == pytest.approx(3.0)
    assert sc.duration_s == 10.0 and sc.mission.start == [-3.0, 5.0, 2.0]
    f.write_text('[mission]\ntrajectory_csv = "missing.csv"\n')
    with pytest.raises(ScenarioError, match="mission.trajectory_csv: no such file"):
        load_scenario(f)
    (tmp_path / "bad.csv").write_text("t,x\n0,1\n")
    f.write_text('[mission]\ntrajectory_csv = "bad.csv"\n')
    with pytest.raises(ScenarioError, match="missing CSV columns"):
        load_scenario(f)


@pytest.mark.parametrize("pert,stochastic", [
    ({}, False), ({"fading_k_db": 6.0}, True), ({"fading_k_db": float("inf")}, False),
    ({"csi_noise_m": 0.1}, True), ({"process_noise_v": 0.2}, True), ({"process_noise_w": 0.2}, True),
])
def test_seed_matters_only_for_random_perturbations(pert, stochastic):
    assert parse_scenario({"perturbations": pert}).perturbations.stochastic is stochastic


# -- property: loading any scenario table either succeeds or raises the named scenario error --
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_SCALARS = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6), st.floats(allow_nan=True, allow_infinity=True),
                     st.text(max_size=8), st.lists(st.floats(-20, 20), max_size=5))
_FIELDS = {
    "platform": ["tilt_deg", "rotor_count", "mass_kg", "omega_min_hz", "omega_max_hz", "inertia_kgm2", "arm_length_m"],
    "controller": ["variant", "horizon", "mu", "ts_s", "q_slack", "planner"],
    "sim": ["duration_s", "control_rate_hz", "plant_rate_hz"],
    "nodes": ["bs", "relay"],
    "jammer": ["power_w", "position", "schedule"],
    "perturbations": ["fading_k_db", "csi_noise_m"],
    "channel": ["noise_power_w", "bandwidth"],
}
_TABLES = st.fixed_dictionaries({}, optional={
    sec: st.dictionaries(st.sampled_from(keys + ["bogus"]), _SCALARS, max_size=3) for sec, keys in _FIELDS.items()})


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_TABLES)
def test_any_scenario_table_loads_or_names_its_error(table):
    import tomli_w

    try:
        sc = parse_scenario(table)
    except ScenarioError as exc:
        lines = str(exc).splitlines()
        assert lines and all(":" in line for line in lines)  # every line names a field (or "scenario")
        return
    assert parse_scenario(tomllib_loads(sc.to_toml())) == sc  # a valid one round-trips
    assert tomli_w.dumps(sc.model_dump(exclude_none=True))


def tomllib_loads(text):
    import tomllib

    return tomllib.loads(text)


def test_antenna_gain_in_dbi():
    """A half-wave dipole's 2.15 dBi is a linear peak gain of 10^0.215 = 1.6406; both fields given must agree;
    the resolved scenario (which writes both) loads again."""
    import tomllib

    sc = parse_scenario({"antenna": {"g_bar_dbi": 2.15}})
    assert sc.antenna.g_bar == pytest.approx(1.640590, rel=1e-6)
    assert relay_pattern(sc.antenna).g_bar == pytest.approx(1.640590, rel=1e-6)
    assert parse_scenario(tomllib.loads(sc.to_toml())) == sc
    assert parse_scenario({"antenna": {"g_bar_dbi": 0.0, "g_bar": 1.0}}).antenna.g_bar == 1.0
    with pytest.raises(ScenarioError, match="g_bar_dbi"):
        parse_scenario({"antenna": {"g_bar_dbi": 3.0, "g_bar": 1.0}})
    with pytest.raises(ScenarioError, match="antenna.g_bar_dbi"):
        parse_scenario({"antenna": {"g_bar_dbi": 45.0}})


def test_capacity_controllers_qp_iteration_cap_comes_from_its_settings_and_the_papers_does_not():
    paper = load_scenario(ROOT / "scenarios" / "nominal_tilted.toml")
    s = nmpc_settings(paper)
    assert (s.iter_max, s.accept_tol) == (NmpcSettings().iter_max, NmpcSettings().accept_tol) == (50, 0.0)
    cap = paper.with_updates({"controller.planner": "capacity"})
    assert nmpc_settings(cap).fingerprint() == NmpcSettings().fingerprint()  # uncapped by default
    capped = cap.with_updates({"controller.capacity.qp_iter_max": 5, "controller.capacity.qp_accept_tol": 1e-6})
    assert (nmpc_settings(capped).iter_max, nmpc_settings(capped).accept_tol) == (5, 1e-6)
    assert nmpc_settings(capped, iter_max=50, accept_tol=None).iter_max == 50  # an explicit value wins, None does not
    assert nmpc_settings(paper.with_updates({"controller.capacity.qp_iter_max": 5})).iter_max == 50  # capacity only
    with pytest.raises(ScenarioError, match="qp_iter_max"):
        paper.with_updates({"controller.capacity.qp_iter_max": 0})
