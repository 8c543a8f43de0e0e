"""A ray-traced scene generated from the scenario's own obstacles (``channel.propagation.scene = "obstacles"``): every
box, prism (a building from a footprint file: ``[buildings]``) and vertical cylinder (a 32-sided prism) as a closed
triangle mesh, and a flat ground, written as binary PLY meshes and a Mitsuba XML file Sionna RT loads, each surface an
ITU-R P.2040 radio material (Sionna's ``itu-radio-material``: a slab of the given thickness; the ground 50 m thick,
a half space: its reflection is the Fresnel coefficient's). The files are cached by their content (a SHA-256 of the
geometry and materials names the folder), so a scene is written once and the tracer's cache keys on its files.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import struct
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .obstacles import Box, Prism, VerticalCylinder

# ITU-R P.2040-3 Table 3's materials as Sionna RT 2 names them
ITU_MATERIALS = ("concrete", "brick", "plasterboard", "wood", "glass", "ceiling_board", "chipboard", "plywood", "marble",
                 "floorboard", "metal", "very_dry_ground", "medium_dry_ground", "wet_ground")
GROUND_THICKNESS_M = 50.0  # a half space: Sionna's slab reflection equals Fresnel's once this thick (measured, notes)
CYLINDER_SIDES = 32


@dataclass(frozen=True)
class Solid:
    """One obstacle's closed surface: a vertical prism over a convex footprint (x, y corners, counter-clockwise) from
    ``z_min`` to ``z_max`` (m), of ``material`` (an ITU name) ``thickness_m`` thick."""

    name: str
    footprint: tuple[tuple[float, float], ...]
    z_min: float
    z_max: float
    material: str
    thickness_m: float


def outline(shape) -> tuple[tuple[tuple[float, float], ...], float, float]:
    """An obstacle's bare shape (``models.obstacles``: a box, a prism, a vertical cylinder as the 32-sided prism that
    holds it) as its footprint's corners (x, y, counter-clockwise, m) and its bottom and top (m)."""
    if isinstance(shape, Box):
        (x0, y0, z0), (x1, y1, z1) = shape.lo, shape.hi
        return ((x0, y0), (x1, y0), (x1, y1), (x0, y1)), z0, z1
    if isinstance(shape, Prism):
        v = np.asarray(shape.footprint, float)
        area2 = np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1])
        v = v if area2 > 0 else v[::-1]
        return tuple(map(tuple, v.tolist())), shape.z_min, shape.z_max
    if isinstance(shape, VerticalCylinder):
        a = 2 * math.pi * np.arange(CYLINDER_SIDES) / CYLINDER_SIDES
        r = shape.radius / math.cos(math.pi / CYLINDER_SIDES)  # the polygon's sides touch the circle: it holds it
        foot = tuple((shape.centre[0] + r * math.cos(t), shape.centre[1] + r * math.sin(t)) for t in a)
        return foot, shape.z_min, shape.z_max
    raise TypeError(f"no outline for an obstacle of type {type(shape).__name__}")


def solid(name: str, shape, material: str, thickness_m: float) -> Solid:
    """The ``Solid`` of an obstacle's bare shape (``outline``)."""
    foot, z_min, z_max = outline(shape)
    return Solid(name, foot, z_min, z_max, material, thickness_m)


def prism_mesh(s: Solid) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (n, 3), triangles (m, 3))`` of a solid's closed surface, each triangle counter-clockwise seen from
    outside (outward normals)."""
    v = np.asarray(s.footprint, float)
    n = len(v)
    verts = np.vstack([np.column_stack([v, np.full(n, s.z_min)]), np.column_stack([v, np.full(n, s.z_max)])])
    tris = []
    for i in range(n):  # walls: bottom i, i+1, top i+1, i (the footprint counter-clockwise: outward to the right)
        j = (i + 1) % n
        tris += [(i, j, n + j), (i, n + j, n + i)]
    for i in range(1, n - 1):  # roof (up) and floor (down), fans of the convex footprint
        tris += [(n, n + i, n + i + 1), (0, i + 1, i)]
    return verts, np.array(tris, int)


def ground_mesh(lo_xy, hi_xy, z: float) -> tuple[np.ndarray, np.ndarray]:
    """A flat rectangle at height ``z`` over ``lo_xy``-``hi_xy``, facing up."""
    (x0, y0), (x1, y1) = lo_xy, hi_xy
    verts = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], float)
    return verts, np.array([(0, 1, 2), (0, 2, 3)], int)


def ply_bytes(verts: np.ndarray, tris: np.ndarray) -> bytes:
    """A binary little-endian PLY of a triangle mesh (float32 vertices, int32 indices)."""
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(verts)}\nproperty float x\nproperty float y\n"
            f"property float z\nelement face {len(tris)}\nproperty list uchar int vertex_indices\nend_header\n").encode()
    body = np.asarray(verts, "<f4").tobytes() + b"".join(struct.pack("<B3i", 3, *map(int, t)) for t in tris)
    return head + body


def scene_xml(solids: Sequence[Solid], ground: tuple | None) -> str:
    """The Mitsuba XML of the solids' meshes (``meshes/<name>.ply``) and the ground's (``meshes/ground.ply``),
    ``ground``: ``(material, thickness_m)`` or None."""
    mats = {(s.material, s.thickness_m) for s in solids} | ({ground} if ground else set())
    lines = ['<scene version="2.1.0">']
    for m, t in sorted(mats):
        lines += [f'\t<bsdf type="itu-radio-material" id="{_mat_id(m, t)}">', f'\t\t<string name="type" value="{m}"/>',
                  f'\t\t<float name="thickness" value="{t!r}"/>', "\t</bsdf>"]
    shapes = [(s.name, _mat_id(s.material, s.thickness_m)) for s in solids] + ([("ground", _mat_id(*ground))] if ground else [])
    for name, mat in shapes:
        lines += [f'\t<shape type="ply" id="mesh-{name}">', f'\t\t<string name="filename" value="meshes/{name}.ply"/>',
                  '\t\t<boolean name="face_normals" value="true"/>', f'\t\t<ref id="{mat}" name="bsdf"/>', "\t</shape>"]
    return "\n".join(lines + ["</scene>"]) + "\n"


def _mat_id(material: str, thickness: float) -> str:
    return f"mat-{material}-{thickness:g}".replace(".", "_")


def write_scene(folder: Path, solids: Sequence[Solid], ground: tuple | None, ground_lo_xy, ground_hi_xy,
                ground_z: float) -> Path:
    """The scene's XML file under ``folder`` (``<folder>/<digest>/scene.xml`` with ``meshes/``): written once per
    content, atomically (a temporary folder renamed), reused afterwards. ``ground``: ``(material, thickness_m)`` or
    None (no ground: an empty scene is free space)."""
    spec = {"solids": [[s.name, s.footprint, s.z_min, s.z_max, s.material, s.thickness_m] for s in solids],
            "ground": [list(ground), list(map(float, ground_lo_xy)), list(map(float, ground_hi_xy)), ground_z]
            if ground else None}
    digest = hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()[:24]
    target = Path(folder) / digest
    xml = target / "scene.xml"
    if xml.is_file():
        return xml
    Path(folder).mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{digest}-", dir=folder))
    (tmp / "meshes").mkdir()
    for s in solids:
        (tmp / "meshes" / f"{s.name}.ply").write_bytes(ply_bytes(*prism_mesh(s)))
    if ground:
        (tmp / "meshes" / "ground.ply").write_bytes(ply_bytes(*ground_mesh(ground_lo_xy, ground_hi_xy, ground_z)))
    (tmp / "scene.xml").write_text(scene_xml(solids, ground))
    try:
        os.replace(tmp, target)
    except OSError:  # another process wrote the same content first: theirs is this one
        import shutil
        shutil.rmtree(tmp, ignore_errors=True)
    return xml
