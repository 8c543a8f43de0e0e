"""The compiled relay grid against the numpy evaluation of the same scene (``RadioScene.relay_grid``)."""

import itertools

import numpy as np
import pytest

from aerorelay.assembly import load_scenario
from aerorelay.assembly.parts import build_scene
from aerorelay.models.axes import axis_set
from aerorelay.models.radio import NodePose
from aerorelay.planning.relay_grid import CompiledRelayGrid

AXES = axis_set(np.radians(np.arange(0.0, 360.0, 30.0)), np.full(12, np.radians(20.0)), np.radians(10.0))
OFFSETS = 0.3 * np.array(list(itertools.product((-1.0, 0.0, 1.0), repeat=3)))


@pytest.mark.parametrize("preset", ["nominal_tilted", "two_jammers", "directional_jammer", "moving_jammer", "rma_av"])
def test_compiled_grid_matches_the_numpy_channel(preset):
    sc = load_scenario(f"scenarios/{preset}.toml")
    scene = build_scene(sc)
    source = scene.name_of("source")
    grid = CompiledRelayGrid(scene, len(OFFSETS), len(AXES), source=source)
    rng = np.random.default_rng(3)
    nj = len(scene.jammers)
    for _ in range(5):
        centre = rng.uniform([-6, -5, 2], [6, 5, 10]) + (12.0 if preset == "rma_av" else 0.0) * np.array([0, 0, 1])
        cand = centre + OFFSETS
        tilt = rng.normal(0, 0.2, 3)
        pose = NodePose(rng.uniform([-6, -5, 2], [6, 5, 12]), (np.array([0, 0, 1.0]) + tilt) / np.linalg.norm(np.array([0, 0, 1.0]) + tilt))
        pj = np.array([j.position for j in scene.jammers]) + rng.normal(0, 1.0, (nj, 3))
        PJ = np.array([j.power for j in scene.jammers]) * rng.uniform(0.5, 2.0, nj)
        want = scene.relay_grid(0.0, cand, AXES, {source: pose}, jammer_positions=pj, jammer_powers=PJ)
        got = grid(cand, AXES, pose, pj, PJ)
        assert got.shape == want.shape == (len(OFFSETS), len(AXES))
        # the symbolic dipole divides by sin^2 + 1e-6 (models.antenna.SYMBOLIC_AXIS_EPS): relative
        # 1e-6 / sin^2 per gain, so compared where every link is > 3 deg off the relay's axis
        far = _min_sin2(cand, scene, pose.position, pj) > np.sin(np.radians(3.0)) ** 2
        assert far.mean() > 0.5
        np.testing.assert_allclose(got[far], want[far], rtol=2e-3, atol=1e-12)
        assert np.all(np.isfinite(got)) and np.all(got >= 0.0)


def _min_sin2(cand, scene, p_source, pj):
    """``(M, K)``: the smallest sin^2 between the relay's axis and any of its links."""
    others = [p_source, scene.fixed_pose(scene.name_of("base_station")).position, *pj]
    worst = np.ones((len(cand), len(AXES)))
    for q in others:
        d = q - cand
        c = (d / np.linalg.norm(d, axis=1, keepdims=True)) @ AXES.T
        worst = np.minimum(worst, 1.0 - c * c)
    return worst


def test_silent_jammer_and_a_jammer_on_the_relay():
    scene = build_scene(load_scenario("scenarios/nominal_tilted.toml"))
    grid = CompiledRelayGrid(scene, len(OFFSETS), len(AXES), source="source")
    pose = NodePose(np.array([-3.0, 5.8, 1.7]), np.array([0, 0, 1.0]))
    cand = np.array([-5.0, 2.0, 4.0]) + OFFSETS
    off = grid(cand, AXES, pose, np.array([[-6.95, -5.79, 1.72]]), np.array([0.0]))
    quiet = scene.relay_grid(0.0, cand, AXES, {"source": pose}, jammer_powers=np.zeros(1))
    np.testing.assert_allclose(off, quiet, rtol=2e-4)
    on_relay = grid(cand, AXES, pose, cand[13:14], np.array([1.0]))  # the jammer sits on candidate 13
    assert np.all(np.isfinite(on_relay)) and np.all(on_relay[13] == 0.0)


def test_size_mismatch_raises_naming_the_sizes():
    scene = build_scene(load_scenario("scenarios/nominal_tilted.toml"))
    grid = CompiledRelayGrid(scene, len(OFFSETS), len(AXES), source="source")
    pose = NodePose(np.zeros(3), np.array([0, 0, 1.0]))
    with pytest.raises(ValueError, match="27 positions, 21 axes, 1 jammer"):
        grid(np.zeros((26, 3)), AXES, pose, np.zeros((1, 3)), np.ones(1))
    with pytest.raises(ValueError, match="27 positions, 21 axes, 1 jammer"):
        grid(np.zeros((27, 3)), AXES, pose, np.zeros((2, 3)), np.ones(2))
    with pytest.raises(ValueError, match="27 positions, 21 axes, 1 jammer"):
        grid(np.zeros((27, 3)), AXES[:-1], pose, np.zeros((1, 3)), np.ones(1))
