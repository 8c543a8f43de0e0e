"""Settings that do not apply are refused (config.applies, issue 60 item 4, as acados' make_consistent): generated
from the table, each field given a non-default value where its rule says it does not apply is refused naming it and
where it would apply; a default never is (a fully resolved file loads again); a file's setting made dormant by a
--set that switches what applies is named in a warning, not refused."""

from __future__ import annotations

import logging

import pytest

import aerorelay as ar
from aerorelay.config import ScenarioError
from aerorelay.config.applies import ANTENNA, BOUND, CHANNEL, ESTIMATION, JAMMER, MISSION, PROPAGATION

NOMINAL = "scenarios/nominal_tilted.toml"  # paper units, free space, a dipole, an always-on isotropic static oracle jammer
SECTIONS = {"channel": CHANNEL, "channel.propagation": PROPAGATION, "antenna": ANTENNA, "jammer": JAMMER,
            "estimation": ESTIMATION, "mission": MISSION, "bound": BOUND}


def _cases():
    base = ar.load_scenario(NOMINAL)
    for path, table in SECTIONS.items():
        section = base
        for part in path.split("."):
            section = getattr(section, part)
        for rule in table:
            if rule.when(section, base):
                continue
            names = type(section).model_fields if rule.fields == ("*",) else rule.fields
            yield from (f"{path}.{n}" for n in names)


CASES = sorted(set(_cases()))



def test_the_table_covers_a_real_number_of_settings():
    assert len(CASES) >= 30, CASES


@pytest.mark.parametrize("key", CASES)
def test_a_setting_that_changes_nothing_here_is_refused_by_name(key):
    base = ar.load_scenario(NOMINAL)
    value: object = base
    for part in key.split("."):
        value = getattr(value, part)
    new = {bool: lambda v: not v}.get(type(value), lambda v: None)(value)
    if new is None:
        new = {"on_s": 3.0, "off_s": 2.0, "center_m": [1.0, 2.0, 3.0], "radius_m": 5.0, "period_s": 20.0,
               "point_at": "bs", "boresight": [1.0, 0.0, 0.0], "path": "minimum_jerk", "paths_sum": "coherent",
               "origin_m": [1.0, 0.0, 0.0], "ulog_offset_m": [1.0, 0.0, 0.0], "reference_loss_db": 40.0,
               "bs_axis": [0.0, 1.0, 0.0], "search_min_m": [-50.0, -50.0, 0.0], "search_max_m": [50.0, 50.0, 20.0],
               "building_material": "glass", "ground_material": "wet_ground"}.get(key.split(".")[-1])
    if new is None:
        new = value * 0.5 if isinstance(value, (int, float)) and value else 0.5
        if isinstance(value, int):
            new = max(int(value) // 2, 1) if value > 1 else 2
    section, name = key.rsplit(".", 1)
    with pytest.raises(ScenarioError) as exc:  # this table's refusal, or the section's own check before it, naming it
        ar.load_scenario(NOMINAL, set={key: new})
    said = str(exc.value)
    assert said.startswith(f"{key}: applies only where") or (said.startswith(f"{section}: ") and name in said), said


def test_a_default_is_never_refused_and_a_switch_by_set_warns(tmp_path, caplog):
    resolved = tmp_path / "resolved.toml"
    resolved.write_text(ar.load_scenario(NOMINAL).to_toml())  # every default spelled out, inapplicable ones too
    ar.load_scenario(resolved)
    physical = tmp_path / "physical.toml"
    physical.write_text(ar.load_scenario(NOMINAL, set={"channel.units": "physical", "channel.bandwidth_hz": 1e7}).to_toml())
    with caplog.at_level(logging.WARNING):
        switched = ar.load_scenario(physical, set={"channel.units": "normalized"})
    assert "bandwidth_hz" not in switched.to_toml()  # a run folder's text says what flies, and loads again
    (tmp_path / "again.toml").write_text(switched.to_toml())
    ar.load_scenario(tmp_path / "again.toml")
    assert any("channel.bandwidth_hz = 10000000.0 (from the file) applies only where channel.units = 'physical'"
               in r.getMessage() for r in caplog.records)
    normalized = physical.read_text().replace('units = "physical"', 'units = "normalized"')
    (tmp_path / "both.toml").write_text(normalized)
    with pytest.raises(ScenarioError, match=r"channel\.bandwidth_hz: applies only where channel\.units = 'physical'"):
        ar.load_scenario(tmp_path / "both.toml")
