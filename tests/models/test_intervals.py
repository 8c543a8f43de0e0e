"""Bounds of a link's geometry and an antenna's gain over boxes and intervals (models/intervals.py,
``gain_bounds``): every sample of the box lies inside the bound; the bounds said to be exact are reached
by a sample within the sampling's resolution (hypothesis over boxes, axes and patterns)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from aerorelay.models.antenna import CosinePattern, DipolePattern, IsotropicPattern, SinPowerPattern, TabulatedPattern, gain_bounds
from aerorelay.models.intervals import axis_cos_range, cone_cos_range, distance_range, elevation_range, link_ranges

coord = st.floats(-30.0, 30.0, allow_nan=False)
size = st.floats(0.01, 8.0, allow_nan=False)


def _box(draw_lo, draw_size):
    lo = np.array(draw_lo, float)
    return lo, lo + np.array(draw_size, float)


def _samples(lo, hi, n=4000, seed=0):
    rng = np.random.default_rng(seed)
    corners = np.array([[lo[0] if i & 1 else hi[0], lo[1] if i & 2 else hi[1], lo[2] if i & 4 else hi[2]] for i in range(8)])
    inner = lo + (hi - lo) * rng.uniform(size=(n, 3))
    faces = inner.copy()
    faces[: n // 3, 2] = lo[2]
    faces[n // 3: 2 * n // 3, 2] = hi[2]
    near = np.clip(0.0, lo, hi)  # the box's point nearest the origin, and on its top and bottom faces
    return np.vstack([corners, inner, faces, near, [near[0], near[1], lo[2]], [near[0], near[1], hi[2]]])


@settings(max_examples=150, deadline=None)
@given(st.tuples(coord, coord, coord), st.tuples(size, size, size))
def test_distance_and_elevation_ranges_hold_every_point_of_the_box_and_are_reached(lo, extent):
    d_lo, d_hi = _box(lo, extent)
    pts = _samples(d_lo, d_hi)
    r = np.linalg.norm(pts, axis=1)
    r_min, r_max = distance_range(d_lo, d_hi)
    assert r.min() >= r_min - 1e-9 and r.max() <= r_max + 1e-9
    assert r_max - r.max() < 1e-9  # a corner is the farthest point
    s = pts[:, 2] / np.where(r > 0, r, 1.0)
    s_lo, s_hi = elevation_range(d_lo, d_hi)
    assert s.min() >= s_lo - 1e-9 and s.max() <= s_hi + 1e-9
    # exact: reached within the sampling's resolution (the extremes lie on the box's edges), unless the box
    # holds the origin (a zero-length link: every direction, [-1, 1] said) or all but touches it (lo = (0, 1e-235,
    # -8e-202) was found: the extreme directions lie within 1e-200 m of the origin, where no sample falls)
    if not np.all((d_lo <= 0.0) & (d_hi >= 0.0)) and r_min > 1e-6 * float(np.max(d_hi - d_lo)):
        assert s_hi - s.max() < 0.05 and s.min() - s_lo < 0.05
    # link_ranges: both at once, and the reverse link's (-d) sines from the samples of the reversed box
    ranges = link_ranges(d_lo, d_hi)
    assert np.allclose(ranges, (r_min, r_max, s_lo, s_hi), rtol=0.0, atol=0.0)
    rev_lo, rev_hi = elevation_range(-d_hi, -d_lo)
    assert rev_lo == -s_hi and rev_hi == -s_lo


@settings(max_examples=150, deadline=None)
@given(st.tuples(coord, coord, coord), st.tuples(size, size, size), st.tuples(coord, coord, coord))
def test_the_cosine_to_an_axis_over_a_box_lies_in_its_interval(lo, extent, raw_axis):
    axis = np.array(raw_axis, float)
    if np.linalg.norm(axis) < 1e-3:
        axis = np.array([0.0, 0.0, 1.0])
    axis = axis / np.linalg.norm(axis)
    d_lo, d_hi = _box(lo, extent)
    pts = _samples(d_lo, d_hi)
    r = np.linalg.norm(pts, axis=1)
    c = (pts @ axis)[r > 0] / r[r > 0]
    c_lo, c_hi = axis_cos_range(d_lo, d_hi, axis)
    assert c.min() >= c_lo - 1e-9 and c.max() <= c_hi + 1e-9


@settings(max_examples=100, deadline=None)
@given(st.floats(-1.0, 1.0), st.floats(0.0, 2.0), st.floats(0.0, 1.2))
def test_an_axis_in_a_tilt_cone_makes_every_cosine_of_its_interval_and_no_other(s0, width, tilt):
    s1 = min(1.0, s0 + width)
    c_lo, c_hi = cone_cos_range(s0, s1, tilt)
    rng = np.random.default_rng(1)
    e = np.arcsin(rng.uniform(s0, s1, 3000))
    t = rng.uniform(0.0, tilt, 3000)
    yaw = rng.uniform(-np.pi, np.pi, 3000)
    c = np.sin(e) * np.cos(t) + np.cos(e) * np.sin(t) * np.cos(yaw)  # u . a: link at elevation e, axis tilted t
    assert c.min() >= c_lo - 1e-9 and c.max() <= c_hi + 1e-9


PATTERNS = [DipolePattern(1.64), SinPowerPattern(3.0, 2.0), IsotropicPattern(1.5), CosinePattern(4.0, 2.0, 0.05),
            CosinePattern(1.0, 0.0, 0.0), TabulatedPattern((0.0, 30.0, 90.0, 150.0, 180.0), (0.1, 0.9, 2.0, 0.5, 0.2))]


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(range(len(PATTERNS))), st.floats(-1.0, 1.0), st.floats(0.0, 2.0))
def test_gain_bounds_are_a_patterns_least_and_largest_gain_over_an_interval(k, lo, width):
    """Against dense sampling of the pattern itself: every sample inside, both ends reached."""
    pattern = PATTERNS[k]
    hi = min(1.0, lo + width)
    c = np.r_[np.linspace(lo, hi, 20001), lo, hi]
    g = pattern.gain_from_cos(c)
    least, most = gain_bounds(pattern, lo, hi)
    assert g.min() >= least - 1e-12 and g.max() <= most + 1e-12
    assert most - g.max() < 1e-3 * max(1.0, most) and g.min() - least < 1e-3 * max(1.0, most)
