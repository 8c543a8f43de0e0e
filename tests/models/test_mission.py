import numpy as np
import pytest

from aerorelay.assembly import parse_scenario
from aerorelay.models.geometry import rotation_zyx
from aerorelay.models.mission import CsvPath, MinimumJerkPath

WPS = parse_scenario({}).mission.waypoints


def test_waypoints_hit_with_rest():
    path = MinimumJerkPath(WPS)
    for t, *p in WPS:
        s = path.state(t)
        np.testing.assert_allclose(s.p, p, atol=1e-12)
        np.testing.assert_allclose(s.v, 0, atol=1e-12)
        np.testing.assert_allclose(s.a, 0, atol=1e-12)
    assert path.duration == 47.0


def test_derivatives_consistent_and_acceleration_continuous():
    path = MinimumJerkPath(WPS)
    h = 1e-5
    for t in np.linspace(0.1, 46.9, 40):
        s = path.state(t)
        np.testing.assert_allclose(s.v, (path.state(t + h).p - path.state(t - h).p) / (2 * h), atol=1e-6)
        np.testing.assert_allclose(s.a, (path.state(t + h).v - path.state(t - h).v) / (2 * h), atol=1e-5)
    for t in (12.0, 17.0, 28.0, 38.0):
        np.testing.assert_allclose(path.state(t - 1e-7).a, path.state(t + 1e-7).a, atol=1e-5)


def test_attitude_follows_acceleration():
    path = MinimumJerkPath(WPS)
    s = path.state(5.0)
    R = rotation_zyx(path.attitude(5.0))
    thrust = s.a + np.array([0, 0, 9.81])
    np.testing.assert_allclose(R[:, 2], thrust / np.linalg.norm(thrust), atol=1e-12)


def test_csv_path(tmp_path):
    f = tmp_path / "traj.csv"
    f.write_text("t,px,py,pz,vx,vy,vz,ax,ay,az\n0,0,0,1,1,0,0,0,0,0\n2,2,0,1,1,0,0,0,0,0\n")
    path = CsvPath(f)
    s = path.state(1.0)
    np.testing.assert_allclose(s.p, [1, 0, 1])
    assert path.duration == 2.0
    bad = tmp_path / "bad.csv"
    bad.write_text("t,px,py\n0,0,0\n")
    with pytest.raises(ValueError, match="missing CSV columns"):
        CsvPath(bad)
