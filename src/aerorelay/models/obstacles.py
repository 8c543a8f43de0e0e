"""Obstacles as exact signed distances: axis-aligned boxes (buildings) and vertical cylinders
(towers, poles), each grown by a margin. Pure numpy; world frame, metres.

``signed_distance(p)`` is the Euclidean distance from ``p`` to the grown obstacle, negative inside
(the depth to its surface). ``closest_point(p)`` is the nearest point of its surface, and
``separating_plane(p)`` the plane through that point with the outward unit normal toward ``p``: the
obstacle is convex, so it lies entirely on the plane's far side, and a controller that keeps
``n . x >= n . q`` keeps out (a linear constraint per stage, chosen from the previous plan).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


class Grown:
    """What every shape answers from its ``_core`` (the signed distance to the shape itself, its nearest surface point
    and the outward normal there) and its ``margin`` (m): the grown shape's signed distance and nearest point."""

    margin: float

    def _core(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        raise NotImplementedError

    def signed_distance(self, p) -> np.ndarray:
        """The signed distance (m) of points ``p`` ``(..., 3)`` to the grown shape (negative inside)."""
        return self._core(np.asarray(p, float))[0] - self.margin

    def closest_point(self, p) -> np.ndarray:
        """The nearest point of the grown shape's surface (m, world)."""
        _, q, n = self._core(np.asarray(p, float))
        return q + self.margin * n


@dataclass(frozen=True)
class Box(Grown):
    """An axis-aligned box ``[lo, hi]`` (m, world) grown by ``margin`` m on every side (its corners
    rounded: the set of points within ``margin`` of the box)."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    margin: float = 0.0

    def __post_init__(self):
        if any(h <= lo for lo, h in zip(self.lo, self.hi, strict=True)) or self.margin < 0:
            raise ValueError(f"box: lo {self.lo} must be below hi {self.hi} on every axis and margin >= 0")

    def _core(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The signed distance to the box itself (no margin), the nearest point of its surface and the
        outward unit normal there ``(..., 3)``."""
        lo, hi = np.asarray(self.lo, float), np.asarray(self.hi, float)
        c, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
        q = np.abs(p - c) - h
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
        inside = np.minimum(q.max(axis=-1), 0.0)
        nearest = np.clip(p, lo, hi)
        # inside: push the coordinate closest to a face onto that face
        axis = np.argmax(q, axis=-1)
        into = (q.max(axis=-1) < 0)[..., None] & (np.arange(3) == axis[..., None])
        face = np.where(p - c >= 0, hi, lo)
        nearest = np.where(into, face, nearest)
        # on or inside the box: the normal of the nearest face; outside: toward p
        face_normal = np.where(np.arange(3) == axis[..., None], np.where(p - c >= 0, 1.0, -1.0), 0.0)
        return outside + inside, nearest, _normal(p, nearest, outside, face_normal)



@dataclass(frozen=True)
class VerticalCylinder(Grown):
    """A vertical cylinder of ``radius`` m about ``(x, y) = centre`` from ``z_min`` to ``z_max`` (m,
    world) grown by ``margin`` m (edges rounded)."""

    centre: tuple[float, float]
    radius: float
    z_min: float
    z_max: float
    margin: float = 0.0

    def __post_init__(self):
        if self.radius <= 0 or self.z_max <= self.z_min or self.margin < 0:
            raise ValueError("vertical cylinder: radius > 0, z_min < z_max and margin >= 0")

    def _core(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """As ``Box._core``."""
        c = np.asarray(self.centre, float)
        rel = p[..., 0:2] - c
        r = np.linalg.norm(rel, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            radial = np.where(r[..., None] > 0, rel / r[..., None], np.array([1.0, 0.0]))
        zc, hz = 0.5 * (self.z_min + self.z_max), 0.5 * (self.z_max - self.z_min)
        a, b = r - self.radius, np.abs(p[..., 2] - zc) - hz  # radial and vertical excess
        outside = np.hypot(np.maximum(a, 0.0), np.maximum(b, 0.0))
        inside = np.minimum(np.maximum(a, b), 0.0)
        # nearest surface point: clamp outside; inside onto the nearer of the side and the caps
        r_near = np.where((a < 0) & (b < 0) & (a >= b), self.radius, np.minimum(r, self.radius))
        z = p[..., 2]
        z_near = np.clip(z, self.z_min, self.z_max)
        cap = (a < 0) & (b < 0) & (b > a)
        z_near = np.where(cap, np.where(z >= zc, self.z_max, self.z_min), z_near)
        xy = c + radial * r_near[..., None]
        nearest = np.concatenate([xy, z_near[..., None]], axis=-1)
        # on or inside: the side's radial normal or the nearer cap's; outside: toward p
        side = np.concatenate([radial, np.zeros_like(z[..., None])], axis=-1)
        up = np.where(z >= zc, 1.0, -1.0)[..., None] * np.array([0.0, 0.0, 1.0])
        return outside + inside, nearest, _normal(p, nearest, outside, np.where((b > a)[..., None], up, side))



@dataclass(frozen=True)
class Prism(Grown):
    """A vertical prism: a convex polygon ``footprint`` (its ``(x, y)`` corners, m, world, in order around it, either
    way) extruded from ``z_min`` to ``z_max`` (m, world), grown by ``margin`` m (edges rounded): a building of any
    orientation (a footprint turned 25 deg is not its bounding box)."""

    footprint: tuple[tuple[float, float], ...]
    z_min: float
    z_max: float
    margin: float = 0.0

    def __post_init__(self):
        v = np.asarray(self.footprint, float)
        if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3 or not np.all(np.isfinite(v)):
            raise ValueError(f"prism: the footprint needs 3 or more finite (x, y) corners, got {self.footprint}")
        if not (self.z_max > self.z_min) or self.margin < 0:
            raise ValueError("prism: z_min < z_max and margin >= 0")
        edges = np.roll(v, -1, axis=0) - v
        if np.any(np.linalg.norm(edges, axis=1) <= 1e-9):
            raise ValueError("prism: the footprint repeats a corner")
        turn = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
        if not (np.all(turn > 1e-12) or np.all(turn < -1e-12)):
            raise ValueError("prism: the footprint is not convex (or has three corners in a line): split it into convex "
                             "parts, one prism each")
        if turn[0] < 0:  # clockwise: counter-clockwise from here on (outward normals to the right of each edge)
            v, edges = v[::-1].copy(), (np.roll(v[::-1], -1, axis=0) - v[::-1])
        # the edges' winding number must be one turn: a star polygon turns the same way at every corner too
        angles = np.arctan2(edges[:, 1], edges[:, 0])
        total = np.sum(np.angle(np.exp(1j * (np.roll(angles, -1) - angles))))
        if abs(total - 2 * np.pi) > 1e-6:
            raise ValueError("prism: the footprint crosses itself")
        object.__setattr__(self, "_v", v)
        object.__setattr__(self, "_e", edges)
        object.__setattr__(self, "_n", np.column_stack([edges[:, 1], -edges[:, 0]]) / np.linalg.norm(edges, axis=1)[:, None])

    def _core(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """As ``Box._core``."""
        v, e, nrm = self._v, self._e, self._n  # type: ignore[attr-defined]
        xy = p[..., None, 0:2]  # (..., 1, 2) against every edge (n, 2)
        s = np.clip(np.sum((xy - v) * e, axis=-1) / np.sum(e * e, axis=-1), 0.0, 1.0)
        foot = v + s[..., None] * e  # the nearest point of each edge
        d = np.linalg.norm(xy - foot, axis=-1)
        k = np.argmin(d, axis=-1)
        dist = np.take_along_axis(d, k[..., None], axis=-1)[..., 0]
        near_xy = np.take_along_axis(foot, k[..., None, None].repeat(2, axis=-1), axis=-2)[..., 0, :]
        inside_xy = np.all(np.sum((xy - v) * nrm, axis=-1) <= 0.0, axis=-1)
        a = np.where(inside_xy, -dist, dist)  # the footprint's signed distance
        zc, hz = 0.5 * (self.z_min + self.z_max), 0.5 * (self.z_max - self.z_min)
        z = p[..., 2]
        b = np.abs(z - zc) - hz
        outside = np.hypot(np.maximum(a, 0.0), np.maximum(b, 0.0))
        inside = np.minimum(np.maximum(a, b), 0.0)
        cap = (a < 0) & (b < 0) & (b > a)
        side_inside = (a < 0) & (b < 0) & (a >= b)
        q_xy = np.where((a > 0)[..., None] | side_inside[..., None], near_xy, p[..., 0:2])
        q_z = np.where(cap, np.where(z >= zc, self.z_max, self.z_min), np.clip(z, self.z_min, self.z_max))
        nearest = np.concatenate([q_xy, q_z[..., None]], axis=-1)
        side = np.concatenate([nrm[k], np.zeros_like(z[..., None])], axis=-1)  # the nearest edge's outward normal
        up = np.where(z >= zc, 1.0, -1.0)[..., None] * np.array([0.0, 0.0, 1.0])
        return outside + inside, nearest, _normal(p, nearest, outside, np.where((b > a)[..., None], up, side))



Obstacle = Box | VerticalCylinder | Prism


def _normal(p: np.ndarray, nearest: np.ndarray, outside: np.ndarray, on_surface: np.ndarray) -> np.ndarray:
    """The outward unit normal at ``nearest``: toward ``p`` when ``p`` is outside (``outside`` > 0, its
    distance), else ``on_surface`` (the face's)."""
    out = (np.asarray(outside) > 1e-12)[..., None]
    n = np.where(out, p - nearest, on_surface)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)  # normalized again: |p - nearest| / outside loses digits near the surface


def separating_plane(obstacle: Obstacle, p) -> tuple[np.ndarray, float]:
    """``(n, c)``: the plane ``n . x = c`` through the grown obstacle's nearest surface point to ``p``
    with the outward unit normal ``n``; the whole obstacle lies in ``n . x <= c`` (convexity), so
    ``n . x >= c`` keeps a point out of it."""
    n, c = separating_planes(obstacle, np.asarray(p, float)[None, :])
    return n[0], float(c[0])


def separating_planes(obstacle: Obstacle, points) -> tuple[np.ndarray, np.ndarray]:
    """``separating_plane`` for each of ``points`` ``(n, 3)``: normals ``(n, 3)`` and offsets ``(n,)``."""
    _, q, n = obstacle._core(np.asarray(points, float))
    return n, np.sum(n * (q + obstacle.margin * n), axis=-1)


def obstacle_model(cfg, margin: bool = True) -> Obstacle:
    """The shape of an ``[[obstacles]]`` table (``config.obstacles.ObstacleConfig``), grown by its
    margin (``margin=False``: the obstacle itself, what a vehicle must never enter)."""
    m = cfg.margin_m if margin else 0.0
    if cfg.kind == "box":
        return Box(tuple(cfg.min_m), tuple(cfg.max_m), m)
    if cfg.kind == "prism":
        return Prism(tuple((float(x), float(y)) for x, y in cfg.footprint_m), cfg.z_min_m, cfg.z_max_m, m)
    return VerticalCylinder(tuple(cfg.centre_m), cfg.radius_m, cfg.z_min_m, cfg.z_max_m, m)


def inside_any(obstacles, p) -> np.ndarray:
    """Whether each point ``p`` ``(..., 3)`` lies inside any of ``obstacles`` (strictly)."""
    return clearance(obstacles, p) < 0


GOLDEN_STEPS = 64  # golden-section steps of segment_clearance: the interval shrinks to 0.618^64 ~ 4e-14 of the segment


def segment_clearance(obstacle: Obstacle, a, b) -> np.ndarray:
    """The smallest signed distance (m) from ``obstacle`` to each straight segment ``a[i] -> b[i]``
    (``(n, 3)`` each, m, world): negative when the segment passes inside. Exact up to
    ``GOLDEN_STEPS`` golden-section steps along each segment: the signed distance of a convex set is
    convex along a line, so its minimum over the segment is found without sampling (a 1 cm wall
    between two samples is not missed)."""
    a, b = np.atleast_2d(np.asarray(a, float)), np.atleast_2d(np.asarray(b, float))
    d = b - a
    f = lambda s: obstacle.signed_distance(a + s[:, None] * d)
    lo, hi = np.zeros(len(a)), np.ones(len(a))
    g = (np.sqrt(5.0) - 1.0) / 2.0
    for _ in range(GOLDEN_STEPS):
        x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
        left = f(x1) <= f(x2)  # convex: the minimum lies in [lo, x2], else in [x1, hi]
        hi, lo = np.where(left, x2, hi), np.where(left, lo, x1)
    mid = 0.5 * (lo + hi)
    return np.minimum.reduce([f(np.zeros(len(a))), f(np.ones(len(a))), f(mid)])


def clearance(obstacles, p) -> np.ndarray:
    """The smallest signed distance (m) from each point ``p`` ``(..., 3)`` to ``obstacles`` (inf: none)."""
    p = np.asarray(p, float)
    out = np.full(p.shape[:-1], np.inf)
    for o in obstacles:
        out = np.minimum(out, o.signed_distance(p))
    return out


def pushed_out(obstacles, p) -> np.ndarray:
    """``p`` (3,) moved onto the nearest surface of the grown obstacle it lies in (unchanged outside
    every obstacle). Repeated a few times for overlapping obstacles."""
    q = np.asarray(p, float).copy()
    for _ in range(4):
        inside = [o for o in obstacles if float(o.signed_distance(q)) < 0]
        if not inside:
            break
        q = np.asarray(inside[0].closest_point(q), float) + 1e-6 * separating_plane(inside[0], q)[0]
    return q
