"""Safe fleets by default (issue 45, item 2). Before: with ``min_separation_m`` at its default 0 two
relays met 0.047 m apart and were called safe; starts 0.4 m apart were accepted and flown."""

from __future__ import annotations

import pytest

from aerorelay.assembly import parse_scenario
from aerorelay.config import ScenarioError
from aerorelay.config.platform import FOOTPRINT_PER_ARM


def _two(start2, **network):
    return parse_scenario({
        "relays": [{"name": "r1", "start": [-5.0, 4.0, 3.0]}, {"name": "r2", "start": start2}],
        "sources": [{"name": "s", "mission": {"waypoints": [[0, -3.04, 5.79, 1.72], [10, -3.04, 5.79, 1.72]]}}],
        "network": {"routes": [["s", "r1", "r2", "bs"]], **network}})


def test_the_default_separation_is_the_vehicles_size():
    sc = _two([-2.0, 2.0, 3.0])
    # the hexarotor's arm is 0.35 m: footprint 1.5 x 0.35 = 0.525 m, two of them 1.05 m
    assert FOOTPRINT_PER_ARM == 1.5
    assert sc.vehicle_size_m == pytest.approx(1.05) and sc.separation_m == pytest.approx(1.05)
    assert _two([-2.0, 2.0, 3.0], min_separation_m=2.5).separation_m == 2.5


def test_starts_closer_than_the_vehicles_size_are_refused():
    with pytest.raises(ScenarioError, match=r"network\.min_separation_m: relays\[0\] \('r1'\) and relays\[1\] \('r2'\) start 0\.4 m apart"):
        _two([-5.0, 4.4, 3.0])


@pytest.mark.parametrize("value,match", [(0.0, r"network\.min_separation_m: must be in \(0, 100\]"),
                                         (0.5, r"network\.min_separation_m: 0\.5 m is closer than two vehicles can be without "
                                               r"touching \(1\.05 m.*allowed 1\.05-100 m")])
def test_a_separation_below_the_vehicles_size_is_refused(value, match):
    with pytest.raises(ScenarioError, match=match):
        _two([-2.0, 2.0, 3.0], min_separation_m=value)


def test_a_larger_platform_needs_more_room():
    sc = parse_scenario({
        "platform": {"arm_length_m": 1.0},
        "relays": [{"name": "r1", "start": [-6.0, 0.0, 3.0]}, {"name": "r2", "start": [-2.0, 0.0, 3.0]}],
        "sources": [{"name": "s", "mission": {"waypoints": [[0, -3.04, 5.79, 1.72], [10, -3.04, 5.79, 1.72]]}}]})
    assert sc.separation_m == pytest.approx(3.0)
