"""Validation is bounded and exact: its cost does not grow with the mission's length or the
workspace's size beyond stated caps; the alignment reachability is right for any base-station
position; the ground and damaged mission files are named errors."""

import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aerorelay.assembly import load_scenario
from aerorelay.assembly.checks import REACH_MAX_POINTS, REACH_MAX_TIMES, REACH_MAX_WORK, reach_grid
from aerorelay.config import ScenarioError
from aerorelay.models.axes import axis_cone
from aerorelay.models.channel import reachable_mutual_alignment
from aerorelay.models.mission import ulog_cut_at
from tests.models.test_flight_logs import _flight, write_ulog

ROOT = Path(__file__).resolve().parents[2]
NOMINAL = ROOT / "scenarios" / "nominal_tilted.toml"


# ---------------------------------------------------------------- bounded
@settings(max_examples=60, deadline=None)
@given(span=st.lists(st.floats(min_value=0.5, max_value=5000.0), min_size=3, max_size=3),
       cap=st.integers(min_value=8, max_value=REACH_MAX_POINTS))
def test_the_reach_grid_never_exceeds_its_cap_and_covers_the_box(span, cap):
    lo = np.zeros(3)
    hi = np.array(span)
    g = reach_grid(lo, hi, cap)
    assert len(g) <= cap
    np.testing.assert_allclose(g.min(axis=0), lo)
    np.testing.assert_allclose(g.max(axis=0), hi)
    if np.prod(np.ceil(hi) + 1) <= cap:  # small boxes keep the exact 1 m grid
        assert len(g) == np.prod(np.ceil(hi).astype(int) + 1)


@pytest.mark.parametrize("ws,end_s", [(([-7, -6, 0.5], [7, 6, 19]), 47.0), (([-100, -100, 0.5], [100, 100, 60]), 47.0),
                                      (([-500, -500, 0.5], [500, 500, 120]), 1e9)])
def test_the_reachability_work_is_capped(monkeypatch, ws, end_s):
    """Whatever the workspace and the mission's length, the check evaluates at most REACH_MAX_WORK
    (position, axis, instant) triples and REACH_MAX_TIMES instants (counted, not timed)."""
    from aerorelay.assembly import checks as schema

    seen = {}

    def counting(grid, axes, p0, p2):
        seen.update(points=len(grid), axes=len(axes), times=len(p2))
        return np.zeros(len(p2))
    sc = load_scenario(NOMINAL)
    monkeypatch.setattr(schema, "reachable_mutual_alignment", counting)
    schema._reachable_alignment.cache_clear()
    schema._reachable_alignment(sc.platform.model_dump_json(), sc.mission.model_dump_json(), tuple(ws[0]), tuple(ws[1]),
                                (0.0, 0.0, 0.0), end_s)
    assert seen["times"] <= REACH_MAX_TIMES and seen["points"] * seen["axes"] * seen["times"] <= REACH_MAX_WORK
    schema._reachable_alignment.cache_clear()


def test_a_huge_workspace_and_a_very_long_csv_mission_validate(tmp_path):
    """The cases that took 152 s / 6.8 GB or ran out of memory: a 1 km workspace, a CSV whose times
    reach 1e9 s. They load now (the time is measured in docs, not asserted here)."""
    csv = tmp_path / "long.csv"
    csv.write_text("t,px,py,pz,vx,vy,vz,ax,ay,az\n0,-3.04,5.79,1.72,0,0,0,0,0,0\n1,-3.0,5.79,2.0,0,0,0,0,0,0\n"
                   "1e9,-2.0,5.0,3.0,0,0,0,0,0,0\n")
    sc = load_scenario(NOMINAL, set={"controller.workspace.min": [-500, -500, 0.5], "controller.workspace.max": [500, 500, 100],
                                     "mission.trajectory_csv": str(csv), "controller.mu": 0.2})
    assert sc.duration_s == 1e9


# ---------------------------------------------------------------- exact for any base-station position
@settings(max_examples=40, deadline=None)
@given(k=st.integers(min_value=0, max_value=26), which=st.sampled_from(["bs", "source"]))
def test_a_grid_point_on_a_node_is_left_out_not_nan(k, which):
    grid = np.stack(np.meshgrid(*[np.linspace(-1, 1, 3)] * 3, indexing="ij"), -1).reshape(-1, 3) + [0.3, 0.1, 2.0]
    axes = axis_cone(np.radians(15.0), np.radians(5.0))
    node = grid[k].copy()
    p0, p2 = (node, np.array([[4.0, 3.0, 9.0]])) if which == "bs" else (np.array([0.0, 0.0, 0.0]), node[None, :])
    got = reachable_mutual_alignment(grid, axes, p0, p2)
    rest = reachable_mutual_alignment(np.delete(grid, k, axis=0), axes, p0, p2)
    assert np.all(np.isfinite(got)) and np.allclose(got, rest)


@pytest.mark.parametrize("bs", [[0, 0, 0.5], [1, 2, 1.5], [-7, -6, 0.5], [7, 6, 19]])
def test_a_base_station_on_the_reachability_grid_is_valid(bs):
    sc = load_scenario(NOMINAL, set={"nodes.bs": bs})
    assert sc.nodes.bs == [float(v) for v in bs]


# ---------------------------------------------------------------- the ground
@pytest.mark.parametrize("ground", [0.0, -5.0, 0.4])
@pytest.mark.parametrize("what", ["workspace", "waypoints", "jammer_position", "jammer_waypoints", "bs"])
def test_everything_stays_above_the_ground(ground, what):
    below = ground - 0.3
    sets = {"world.ground_z_m": ground}
    sets.update({
        "workspace": {"controller.workspace.min": [-7, -6, below]},
        "waypoints": {"mission.waypoints": [[0, -3.04, 5.79, 1.72], [12, -1.5, 4.29, below]]},
        "jammer_position": {"jammer.position": [-6.95, -5.79, below]},
        "jammer_waypoints": {"jammer.waypoints": [[0, -6.95, -5.79, 1.72], [10, 0, -5.79, below]]},
        "bs": {"nodes.bs": [0, 0, below]},
    }[what])
    with pytest.raises(ScenarioError, match="below"):
        load_scenario(NOMINAL, set=sets)


@pytest.mark.parametrize("kind", ["csv", "ulog"])
def test_flight_files_below_the_ground_are_named(tmp_path, kind):
    if kind == "csv":
        f = tmp_path / "m.csv"
        f.write_text("t,px,py,pz\n0,-3.04,5.79,1.72\n1,-3.0,5.79,0.5\n2,-2.9,5.79,-0.4\n3,-2.8,5.79,1.0\n4,-2.8,5.79,1.5\n")
        sets = {"mission.trajectory_csv": str(f)}
    else:
        f = tmp_path / "m.ulg"
        write_ulog(f, *_flight())
        sets = {"mission.trajectory_ulog": str(f), "mission.ulog_offset_m": [-3.04, 5.79, -2.5]}
    with pytest.raises(ScenarioError, match=f"mission.trajectory_{kind}: .*below ground"):
        load_scenario(NOMINAL, set=sets)


def test_a_vehicle_below_the_ground_is_unsafe_in_supervisor_and_metrics():
    from aerorelay.control.supervisor import SafetyEnvelope
    from aerorelay.sim.metrics import safety_metrics

    env = SafetyEnvelope(np.array([-7, -6, -1.0]), np.array([7, 6, 19.0]), 16.0, 100.0, ground_z_m=0.0)
    x = np.r_[0.0, 0.0, -0.2, np.zeros(9), np.full(6, 60.0)]
    assert any("below the ground" in v for v in env.violations(x))
    p1 = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -0.01]])
    m = safety_metrics(p1, np.zeros(2), np.zeros(2, bool), [-7, -6, -1], [7, 6, 19], 0.05, ground_z_m=0.0)
    assert m["unsafe"] and "below the ground" in m["unsafe_reason"]


# ---------------------------------------------------------------- damaged mission files
@settings(max_examples=25, deadline=None)
@given(cut=st.integers(min_value=1, max_value=2000))
def test_a_ulog_cut_anywhere_inside_a_message_is_named(tmp_path_factory, cut):
    f = tmp_path_factory.mktemp("u") / "m.ulg"
    write_ulog(f, *_flight(n=60))
    data = f.read_bytes()
    assert ulog_cut_at(f) is None
    n = len(data) - cut
    f.write_bytes(data[:n])
    boundaries = _message_ends(data)
    if n in boundaries:  # cut exactly between two messages: nothing to see in the bytes
        return
    assert ulog_cut_at(f) is not None
    with pytest.raises(ScenarioError, match="truncated|not a readable|needs >= 2"):
        load_scenario(NOMINAL, set={"mission.trajectory_ulog": str(f), "mission.ulog_offset_m": [-3.04, 5.79, 0.0]})


def _message_ends(data: bytes) -> set[int]:
    pos, ends = 16, {16}
    while pos + 3 <= len(data):
        pos += 3 + struct.unpack_from("<H", data, pos)[0]
        ends.add(pos)
    return ends


# 1e300 is not representable in a ULog float32 field (inf there is a named error of its own): CSV only
@pytest.mark.parametrize("far,kind", [(3e38, "csv"), (1e300, "csv"), (2e3, "csv"), (3e38, "ulog"), (2e3, "ulog")])
def test_samples_far_from_the_workspace_are_named_with_the_file_and_row(tmp_path, far, kind):
    if kind == "csv":
        f = tmp_path / "m.csv"
        f.write_text(f"t,px,py,pz\n0,-3.04,5.79,1.72\n1,-3.0,5.79,2.0\n2,{far:g},5.79,2.5\n3,-2.8,5.79,3.0\n4,-2.8,5.79,3.5\n")
        sets, row = {"mission.trajectory_csv": str(f)}, "sample 3"
    else:
        f = tmp_path / "m.ulg"
        t, rows = _flight(n=40)
        rows[17, 0] = far
        write_ulog(f, t, rows)
        sets, row = {"mission.trajectory_ulog": str(f), "mission.ulog_offset_m": [-3.04, 5.79, 0.0]}, "sample 18"
    with pytest.raises(ScenarioError, match=f"mission.trajectory_{kind} {row}: .*world.mission_max_distance_m"):
        load_scenario(NOMINAL, set=sets)
