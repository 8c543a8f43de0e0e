"""The scene traced from the scenario's own obstacles (``channel.propagation.scene = "obstacles"``, issue 63 item 3)
against independent values: no obstacles and no ground is free space (Friis, 0.05 dB); the ground alone is the
two-ray link whose reflection is the half-space Fresnel coefficient of ITU-R P.2040's medium dry ground, written out
here from the Recommendation's table; a building between two nodes lets through what two ITU concrete slabs
transmit at normal incidence (P.2040's slab formula, written out here); the files are written once per content."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly.world import generated_scene_file, trace_settings
from aerorelay.config import ScenarioError
from aerorelay.models.antenna import IsotropicPattern
from aerorelay.models.generated_scene import prism_mesh, solid
from aerorelay.models.obstacles import Prism
from aerorelay.models.propagation import wavelength_m
from aerorelay.models.raytrace import RayTracer
from tests.rt_marks import needs_rt

F = 2.4e9
EPS0 = 8.8541878128e-12
ISO = IsotropicPattern(1.0)
UP = np.array([0.0, 0.0, 1.0])
TRACED = {"channel.units": "physical", "channel.propagation.model": "ray_traced", "channel.propagation.scene": "obstacles"}


def _itu(a: float, b: float, c: float, d: float) -> complex:
    """ITU-R P.2040-3 Table 3: eps' = a f^b, sigma = c f^d (f in GHz), eps = eps' - j sigma / (omega eps0)."""
    f = F / 1e9
    return a * f**b - 1j * (c * f**d) / (2 * math.pi * F * EPS0)


CONCRETE = _itu(5.24, 0.0, 0.0462, 0.7822)
MEDIUM_DRY_GROUND = _itu(15.0, -0.1, 0.035, 1.63)


def _scenario(**updates) -> ar.config.Scenario:
    return ar.load_scenario("scenarios/nominal_tilted.toml", set={**TRACED, **updates})


def test_a_solids_surface_is_closed_and_faces_out():
    """Every edge of the mesh is shared by two triangles in opposite directions (closed, consistently oriented) and
    the signed volume is the prism's (outward normals)."""
    foot = ((0.0, 0.0), (4.0, 0.0), (5.0, 3.0), (1.0, 4.0))
    s = solid("b", Prism(foot, 1.0, 7.0), "concrete", 0.2)
    v, t = prism_mesh(s)
    edges = [(a, b) for tri in t for a, b in zip(tri, np.roll(tri, -1), strict=True)]
    assert all((b, a) in edges for a, b in edges) and len(set(edges)) == len(edges)
    volume = sum(np.dot(v[i], np.cross(v[j], v[k])) for i, j, k in t) / 6.0
    area = 0.5 * abs(sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(foot, foot[1:] + foot[:1], strict=True)))
    assert volume == pytest.approx(area * 6.0)


@needs_rt
def test_no_obstacles_and_no_ground_is_free_space():
    sc = _scenario(**{"channel.propagation.ground_material": "none", "channel.propagation.max_depth": 2})
    tracer = RayTracer(trace_settings(sc), cached=False)
    tx = np.array([[0.0, 0.0, 10.0]] * 2)
    rx = np.array([[10.0, 0.0, 10.0], [30.0, 40.0, 3.0]])
    links = tracer.trace(tx, rx)
    friis = (wavelength_m(F) / (4 * np.pi * np.linalg.norm(rx - tx, axis=1))) ** 2
    np.testing.assert_allclose(10 * np.log10(links.gain(ISO, UP, ISO, UP) / friis), 0.0, atol=0.05)
    np.testing.assert_array_equal(links.paths, [1, 1])


@needs_rt
@pytest.mark.parametrize("h1, h2, d", [(10.0, 2.0, 30.0), (3.0, 3.0, 50.0)])
def test_the_ground_alone_is_the_two_ray_link_with_itus_medium_dry_ground(h1, h2, d):
    sc = _scenario(**{"channel.propagation.max_depth": 1})
    tracer = RayTracer(trace_settings(sc), cached=False)
    links = tracer.trace(np.array([[0.0, 0.0, h1]]), np.array([[d, 0.0, h2]]))
    assert links.paths[0] == 2
    amp = np.abs(links.a[0][links.valid[0]])
    los = links.los[0][links.valid[0]]
    d1, d2 = math.hypot(d, h1 - h2), math.hypot(d, h1 + h2)
    lam = wavelength_m(F)
    assert amp[los][0] == pytest.approx(lam / (4 * math.pi * d1), rel=1e-4)
    cos_i = (h1 + h2) / d2
    root = np.sqrt(MEDIUM_DRY_GROUND - (1 - cos_i**2))
    gamma_tm = (MEDIUM_DRY_GROUND * cos_i - root) / (MEDIUM_DRY_GROUND * cos_i + root)
    assert amp[~los][0] / (lam / (4 * math.pi * d2)) == pytest.approx(abs(gamma_tm), rel=2e-3)


@needs_rt
def test_a_building_between_two_nodes_lets_through_two_concrete_slabs():
    """A 10 m concrete block (walls 0.2 m) across the line between two nodes, no ground, refraction traced: the only
    path crosses two walls at normal incidence; each transmits P.2040's slab coefficient
    ``T = (1 - R^2) e^{-jq} / (1 - R^2 e^{-2jq})``, ``R = (1 - n) / (1 + n)``, ``n = sqrt(eps)``, ``q = 2 pi d n / lambda``."""
    block = {"name": "block", "kind": "box", "min_m": [100.0, -5.0, 0.0], "max_m": [110.0, 5.0, 12.0], "margin_m": 0.0}
    sc = _scenario(**{"channel.propagation.ground_material": "none", "channel.propagation.refraction": True,
                      "channel.propagation.max_depth": 2, "obstacles": [block]})
    tracer = RayTracer(trace_settings(sc), cached=False)
    tx, rx = np.array([[85.0, 0.0, 6.0]]), np.array([[130.0, 0.0, 6.0]])
    links = tracer.trace(tx, rx)
    friis = (wavelength_m(F) / (4 * np.pi * 45.0)) ** 2
    n = np.sqrt(CONCRETE)
    r = (1 - n) / (1 + n)
    q = 2 * math.pi * 0.2 * n / wavelength_m(F)
    t = (1 - r**2) * np.exp(-1j * q) / (1 - r**2 * np.exp(-2j * q))
    expected_db = 20 * math.log10(abs(t) ** 2)  # two walls
    got_db = 10 * math.log10(links.gain(ISO, UP, ISO, UP)[0] / friis)
    assert expected_db < -3.0  # a real loss to find
    assert got_db == pytest.approx(expected_db, abs=0.1)
    # without refraction the block stops the link: no path
    shut = RayTracer(trace_settings(sc.with_updates({"channel.propagation.refraction": False})), cached=False)
    assert shut.trace(tx, rx).paths[0] == 0


@needs_rt
def test_the_scene_is_written_once_per_content(tmp_path, monkeypatch):
    monkeypatch.setenv("AERORELAY_CACHE", str(tmp_path))
    block = {"name": "block", "kind": "box", "min_m": [-3.0, -5.0, 0.0], "max_m": [-2.0, -4.0, 3.0]}
    a = generated_scene_file(_scenario(obstacles=[block]))
    stamp = (tmp_path / "scenes").stat().st_mtime_ns, __import__("os").stat(a).st_mtime_ns
    assert generated_scene_file(_scenario(obstacles=[block])) == a
    assert __import__("os").stat(a).st_mtime_ns == stamp[1]
    moved = generated_scene_file(_scenario(obstacles=[block | {"max_m": [-2.0, -4.0, 4.0]}]))
    assert moved != a
    text = open(a).read()
    assert 'value="concrete"' in text and 'value="medium_dry_ground"' in text and "meshes/block.ply" in text


def test_scene_settings_are_refused_where_they_change_nothing():
    with pytest.raises(ScenarioError, match="channel.propagation.ground_material: applies only where"):
        ar.load_scenario("scenarios/nominal_tilted.toml", set={"channel.propagation.ground_material": "wet_ground"})
    block = {"name": "b", "kind": "box", "min_m": [-3.0, -5.0, 0.0], "max_m": [-2.0, -4.0, 3.0], "material": "glass"}
    with pytest.raises(ScenarioError, match=r"obstacles\[0\].material: applies only where"):
        ar.load_scenario("scenarios/nominal_tilted.toml", set={"obstacles": [block]})
    with pytest.raises(ScenarioError, match="scenario's own frame"):
        _scenario(**{"channel.propagation.origin_m": [1.0, 0.0, 0.0]})


@needs_rt
def test_the_district_preset_flies_among_its_footprint_files_buildings_on_their_traced_radio():
    """``scenarios/district_chain.toml``: the GeoJSON's five footprints as six prisms (the L cut in two), the scene
    traced generated from them, the fleet scoring on it (two decisions, reflections of depth 1: the suite's time)."""
    sc = ar.load_scenario("scenarios/district_chain.toml", set={"sim.duration_s": 0.3, "channel.propagation.max_depth": 1})
    names = sorted(o.name for o in sc.obstacle_list)
    assert names == ["building0", "building1", "building2_0", "building2_1", "building3", "building4"]
    assert "building2_0.ply" in "".join(p.name for p in Path(trace_settings(sc).scene).parent.glob("meshes/*"))
    r = ar.simulate(sc)
    assert not r.metrics["unsafe"] and r.metrics["c_min"] > 0
