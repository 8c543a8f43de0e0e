"""Obstacles' signed distances (models/obstacles.py) against brute force: the distance to a dense
sampling of each core surface, inside/outside by the shapes' own inequalities, the nearest point
on the grown surface, the separating plane holding every sample of the obstacle on its far side,
and the 1-Lipschitz property (hypothesis)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from aerorelay.models.obstacles import Box, VerticalCylinder, separating_plane

BOX = Box((1.0, -2.0, 0.0), (4.0, 1.0, 5.0), margin=0.5)
CYL = VerticalCylinder((-3.0, 2.0), 1.5, 0.0, 8.0, margin=0.3)
N = 60  # samples per side of each face: spacing <= 0.14 m


def _box_surface(b: Box) -> np.ndarray:
    lo, hi = np.array(b.lo), np.array(b.hi)
    out = []
    for ax in range(3):
        u, v = [a for a in range(3) if a != ax]
        gu, gv = np.meshgrid(np.linspace(lo[u], hi[u], N), np.linspace(lo[v], hi[v], N))
        for side in (lo[ax], hi[ax]):
            pts = np.zeros((gu.size, 3))
            pts[:, ax], pts[:, u], pts[:, v] = side, gu.ravel(), gv.ravel()
            out.append(pts)
    return np.vstack(out)


def _cyl_surface(c: VerticalCylinder) -> np.ndarray:
    th = np.linspace(0, 2 * np.pi, 4 * N, endpoint=False)
    z = np.linspace(c.z_min, c.z_max, N)
    T, Z = np.meshgrid(th, z)
    side = np.column_stack([c.centre[0] + c.radius * np.cos(T.ravel()), c.centre[1] + c.radius * np.sin(T.ravel()), Z.ravel()])
    r = np.linspace(0, c.radius, N)
    R, T2 = np.meshgrid(r, th)
    caps = [np.column_stack([c.centre[0] + R.ravel() * np.cos(T2.ravel()), c.centre[1] + R.ravel() * np.sin(T2.ravel()),
                             np.full(R.size, zz)]) for zz in (c.z_min, c.z_max)]
    return np.vstack([side, *caps])


SURFACES = {"box": (BOX, _box_surface(BOX)), "cylinder": (CYL, _cyl_surface(CYL))}


def _inside_core(shape, p) -> bool:
    if isinstance(shape, Box):
        return bool(np.all(p > np.array(shape.lo)) and np.all(p < np.array(shape.hi)))
    return bool(np.hypot(p[0] - shape.centre[0], p[1] - shape.centre[1]) < shape.radius and shape.z_min < p[2] < shape.z_max)


coord = st.floats(-8.0, 10.0, allow_nan=False)
point = st.tuples(coord, coord, coord).map(np.array)


@settings(max_examples=150, deadline=None)
@given(p=point, which=st.sampled_from(sorted(SURFACES)))
def test_signed_distance_is_the_distance_to_the_sampled_surface_less_the_margin(p, which):
    shape, surface = SURFACES[which]
    brute = np.linalg.norm(surface - p, axis=1).min()
    core = shape.signed_distance(p) + shape.margin
    assert abs(core) <= brute + 1e-9 and brute <= abs(core) + 0.15  # the samples are at most 0.15 m from any surface point
    assert (core < 0) == _inside_core(shape, p) or abs(core) < 1e-9


@settings(max_examples=150, deadline=None)
@given(p=point, which=st.sampled_from(sorted(SURFACES)))
def test_the_nearest_point_and_the_separating_plane(p, which):
    shape, surface = SURFACES[which]
    d = float(shape.signed_distance(p))
    q = shape.closest_point(p)
    assert abs(float(shape.signed_distance(q))) < 1e-9  # on the grown surface
    assert np.linalg.norm(p - q) == np.float64(abs(d)) or abs(np.linalg.norm(p - q) - abs(d)) < 1e-9
    n, c = separating_plane(shape, p)
    assert abs(np.linalg.norm(n) - 1) < 1e-12
    grown = surface[:, None, :] + shape.margin * np.array([[[0, 0, 1.0]], [[0, 0, -1.0]], [[1.0, 0, 0]], [[-1.0, 0, 0]],
                                                           [[0, 1.0, 0]], [[0, -1.0, 0]]]).reshape(1, 6, 3)
    assert np.all(grown.reshape(-1, 3) @ n <= c + 1e-9)  # the whole obstacle on the far side
    assert (float(n @ p) >= c - 1e-9) == (d >= -1e-12)  # p on the near side exactly when outside


@settings(max_examples=100, deadline=None)
@given(p=point, dp=st.tuples(*[st.floats(-1.0, 1.0)] * 3).map(np.array), which=st.sampled_from(sorted(SURFACES)))
def test_signed_distance_is_one_lipschitz(p, dp, which):
    shape = SURFACES[which][0]
    assert abs(float(shape.signed_distance(p + dp)) - float(shape.signed_distance(p))) <= np.linalg.norm(dp) + 1e-9


def test_bad_shapes_are_named():
    import pytest

    with pytest.raises(ValueError, match="box: lo"):
        Box((0, 0, 0), (0, 1, 1))
    with pytest.raises(ValueError, match="vertical cylinder"):
        VerticalCylinder((0, 0), -1.0, 0, 1)
