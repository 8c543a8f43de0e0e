"""``[wind]`` and ``[[obstacles]]`` as data: they read, name their bad fields, refuse a relay that
starts inside an obstacle's margin and a mission through an obstacle, and a scenario without them
keeps its bound's cache key (the bounds fly no wind: a platform's drag is not in it)."""

from __future__ import annotations

import tomllib

import pytest

from aerorelay.assembly import parse_scenario
from aerorelay.assembly.parts import scenario_bound_key
from aerorelay.config import ScenarioError

TOWER = {"name": "tower", "kind": "cylinder", "centre_m": [-1.5, 5.79], "radius_m": 0.75, "z_min_m": 0.0, "z_max_m": 18.0}


def test_wind_and_obstacles_read_back():
    sc = parse_scenario({"wind": {"mean_m_s": [4.0, 3.0, 0.0], "gusts": True}, "obstacles": [TOWER]})
    assert sc.wind.w20_m_s == pytest.approx(5.0)  # the mean's horizontal speed by default
    assert sc.obstacle_list[0].name == "tower" and sc.obstacle_list[0].margin_m == 1.0
    assert parse_scenario(tomllib.loads(sc.to_toml())) == sc


@pytest.mark.parametrize("obstacle, message", [
    ({"kind": "box", "min_m": [0, 0, 0]}, r"obstacles\.0: .*a box needs max_m"),
    ({"kind": "box", "min_m": [0, 0, 0], "max_m": [1, 1, 1], "radius_m": 2.0}, r"a box has no radius_m"),
    ({"kind": "box", "min_m": [0, 0, 0], "max_m": [1, -1, 1]}, r"min_m .* must be below max_m"),
    ({"kind": "cylinder", "centre_m": [0, 0], "radius_m": 1.0, "z_min_m": 5.0, "z_max_m": 1.0}, r"z_min_m \(5\.0\) must be below"),
    ({"kind": "sphere"}, r"obstacles\.0\.kind"),
    ({**TOWER, "margin_m": -1.0}, r"obstacles\.0\.margin_m"),
])
def test_a_malformed_obstacle_is_a_named_error(obstacle, message):
    with pytest.raises(ScenarioError, match=message):
        parse_scenario({"obstacles": [obstacle]})


def test_a_relay_starting_inside_a_margin_is_refused():
    near = {**TOWER, "centre_m": [-6.95, 7.0]}  # 1.21 m from the relay's start: inside radius + margin
    with pytest.raises(ScenarioError, match=r"nodes\.relay \[-6\.95, 5\.79, 1\.72\] lies 0\.54 m inside obstacles\[0\] \(tower\)"):
        parse_scenario({"obstacles": [near]})


def test_a_mission_through_an_obstacle_is_a_named_error():
    across = {"kind": "box", "min_m": [-2.0, 4.0, 8.5], "max_m": [-1.0, 4.6, 9.5]}  # MRAV-2 hovers in it at 12-17 s
    with pytest.raises(ScenarioError, match=r"mission: the source's path goes through obstacle 'obstacle1'"):
        parse_scenario({"obstacles": [across]})


@pytest.mark.parametrize("wind, message", [
    ({"mean_m_s": [1.0, 2.0]}, r"wind\.mean_m_s"),
    ({"gust_w20_m_s": -1.0}, r"wind\.gust_w20_m_s"),
    ({"observer_time_constant_s": 0.0}, r"wind\.observer_time_constant_s"),
    ({"speed": 3.0}, r"wind\.speed"),
])
def test_a_malformed_wind_is_a_named_error(wind, message):
    with pytest.raises(ScenarioError, match=message):
        parse_scenario({"wind": wind})


def test_the_bound_key_ignores_drag_and_wind_but_not_obstacles():
    plain = parse_scenario({})
    assert scenario_bound_key(parse_scenario({"platform": {"drag_area_m2": [0.2, 0.2, 0.3]}, "wind": {"gusts": True}})) \
        == scenario_bound_key(plain)
    assert scenario_bound_key(parse_scenario({"obstacles": [TOWER]})) != scenario_bound_key(plain)
