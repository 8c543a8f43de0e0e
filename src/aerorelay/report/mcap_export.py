"""A run as an MCAP file Foxglove opens: frames, a 3D scene and the time series (``run.mcap``).

Written with the official ``foxglove-sdk`` (Foxglove's well-known schemas, protobuf-encoded):

- ``/tf`` (``foxglove.FrameTransforms``), every control step: ``world -> <node>`` for every relay and
  source by its node name (``relay``, ``source`` for one relay; positions m, attitudes from the logged
  ZYX Euler angles);
- ``/scene`` (``foxglove.SceneUpdate``), every ``scene_every`` steps: every vehicle with its antenna
  axis (body z arrows), the base station, every jammer (moving ones follow their path), each relay's
  reference, one relay's bound's best position (when the run has a bound), and every hop of every
  route drawn coloured by its SINR (red 0 ... green >= ``SINR_GREEN``);
- ``/scene/static`` once: the workspace box;
- ``/timeseries`` (JSON with a JSON schema), every step: every numeric column of
  ``timeseries.parquet`` (capacity, SINRs, alignment, motor speeds, solve times, ...), plottable
  in Foxglove's Plot panel as ``/timeseries.capacity`` etc.

Log times are the mission's time (ns from 0). ``docs/foxglove_layout.json`` opens all of this.
"""

from __future__ import annotations

import json
from contextlib import contextmanager
from pathlib import Path

import foxglove
import numpy as np
import pandas as pd
from foxglove.channels import FrameTransformsChannel, SceneUpdateChannel
from foxglove.messages import (
    ArrowPrimitive,
    Color,
    CubePrimitive,
    CylinderPrimitive,
    FrameTransform,
    FrameTransforms,
    LinePrimitive,
    LinePrimitiveLineType,
    Point3,
    Pose,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    SpherePrimitive,
    Timestamp,
    Vector3,
)

from ..config import Scenario
from ..sim.log_schema import relays_in, sources_in
from .figures import jammer_tracks

MCAP_FILE = "run.mcap"
SINR_GREEN = 0.1  # links at or above this SINR are drawn green
IDENTITY = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)


def quaternion_xyzw(phi: float, theta: float, psi: float) -> tuple[float, float, float, float]:
    """Unit quaternion ``(x, y, z, w)`` of ``R = Rz(psi) Ry(theta) Rx(phi)`` (body to world)."""
    cr, sr, cp, sp, cy, sy = (np.cos(phi / 2), np.sin(phi / 2), np.cos(theta / 2), np.sin(theta / 2),
                              np.cos(psi / 2), np.sin(psi / 2))
    return (float(sr * cp * cy - cr * sp * sy), float(cr * sp * cy + sr * cp * sy), float(cr * cp * sy - sr * sp * cy),
            float(cr * cp * cy + sr * sp * sy))


def quaternion_zyx(phi: float, theta: float, psi: float) -> Quaternion:
    x, y, z, w = quaternion_xyzw(phi, theta, psi)
    return Quaternion(x=x, y=y, z=z, w=w)


def _stamp(t: float) -> Timestamp:
    return Timestamp(int(t), int(round((t - int(t)) * 1e9)) % 1_000_000_000)


def _ns(t: float) -> int:
    return int(round(t * 1e9))


def _pose(p, q: Quaternion = IDENTITY) -> Pose:
    return Pose(position=Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2])), orientation=q)


def _sinr_color(g: float) -> Color:
    f = float(np.clip(g / SINR_GREEN, 0.0, 1.0))
    return Color(r=1.0 - f, g=f, b=0.1, a=1.0)


def _box_lines(lo, hi) -> LinePrimitive:
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    edges = [(0, 1), (0, 2), (0, 4), (1, 3), (1, 5), (2, 3), (2, 6), (3, 7), (4, 5), (4, 6), (5, 7), (6, 7)]
    pts = [Point3(x=float(c[0]), y=float(c[1]), z=float(c[2])) for e in edges for c in corners[list(e)]]
    return LinePrimitive(type=LinePrimitiveLineType.LineList, pose=_pose((0, 0, 0)), thickness=0.03, points=pts,
                         color=Color(r=0.6, g=0.6, b=0.6, a=0.8))


def _vehicle(name: str, t: float, rgb: tuple[float, float, float]) -> SceneEntity:
    """A vehicle body and its antenna axis (body z), in the vehicle's own frame."""
    color = Color(r=rgb[0], g=rgb[1], b=rgb[2], a=1.0)
    axis_up = Quaternion(x=0.0, y=-np.sqrt(0.5), z=0.0, w=np.sqrt(0.5))  # the arrow's +x turned onto body +z
    return SceneEntity(timestamp=_stamp(t), frame_id=name, id=name, frame_locked=True,
                       cubes=[CubePrimitive(pose=_pose((0, 0, 0)), size=Vector3(x=0.6, y=0.6, z=0.15), color=color)],
                       arrows=[ArrowPrimitive(pose=_pose((0, 0, 0), axis_up), shaft_length=0.6, shaft_diameter=0.04,
                                              head_length=0.15, head_diameter=0.1, color=Color(r=1, g=1, b=1, a=1))])


def _marker(entity: str, t: float, p, rgb, size: float = 0.3) -> SceneEntity:
    return SceneEntity(timestamp=_stamp(t), frame_id="world", id=entity,
                       spheres=[SpherePrimitive(pose=_pose(p), size=Vector3(x=size, y=size, z=size),
                                                color=Color(r=rgb[0], g=rgb[1], b=rgb[2], a=1.0))])


def _link(entity: str, t: float, a, b, sinr: float) -> SceneEntity:
    pts = [Point3(x=float(a[0]), y=float(a[1]), z=float(a[2])), Point3(x=float(b[0]), y=float(b[1]), z=float(b[2]))]
    return SceneEntity(timestamp=_stamp(t), frame_id="world", id=entity,
                       lines=[LinePrimitive(type=LinePrimitiveLineType.LineStrip, pose=_pose((0, 0, 0)), thickness=0.05,
                                            points=pts, color=_sinr_color(sinr))])


def _timeseries_schema(columns: list[str]) -> foxglove.Schema:
    props = {c: {"type": "number"} for c in columns}
    return foxglove.Schema(name="aerorelay.Timeseries", encoding="jsonschema",
                           data=json.dumps({"type": "object", "properties": props}).encode())


def numeric_columns(df: pd.DataFrame) -> list[str]:
    """The time-series columns written to ``/timeseries``: numbers and flags, not text (the QP's status,
    ``<relay>.qp_status``; a flight's ``flight_mode``)."""
    return [c for c in df.columns if pd.api.types.is_numeric_dtype(df[c]) or pd.api.types.is_bool_dtype(df[c])]


@contextmanager
def _mcap_channels(path: Path, sc: Scenario, cols: list[str]):
    """Open ``path`` as MCAP with the channels ``/tf``, ``/scene``, ``/scene/static`` (the workspace
    box, logged once) and ``/timeseries`` of ``cols``; yields ``(tf, scene, series)``."""
    ctx = foxglove.Context()
    with foxglove.open_mcap(str(path), allow_overwrite=True, context=ctx):
        tf = FrameTransformsChannel("/tf", context=ctx)
        scene = SceneUpdateChannel("/scene", context=ctx)
        static = SceneUpdateChannel("/scene/static", context=ctx)
        series = foxglove.Channel("/timeseries", schema=_timeseries_schema(cols), message_encoding="json", context=ctx)
        ws = sc.controller.workspace
        static.log(SceneUpdate(entities=[SceneEntity(timestamp=_stamp(0.0), frame_id="world", id="workspace",
                                                     lines=[_box_lines(ws.min, ws.max)])]), log_time=0)
        yield tf, scene, series


def _frame(name: str, t: float, p, eta) -> FrameTransform:
    """``world -> name`` at position ``p`` (m) and ZYX Euler angles ``eta`` (rad)."""
    return FrameTransform(timestamp=_stamp(t), parent_frame_id="world", child_frame_id=name,
                          translation=Vector3(x=p[0], y=p[1], z=p[2]), rotation=quaternion_zyx(*eta))


def _base_station(name: str, t: float, p0: np.ndarray) -> SceneEntity:
    return SceneEntity(timestamp=_stamp(t), frame_id="world", id=name,
                       cylinders=[CylinderPrimitive(pose=_pose(p0 + [0, 0, 0.5]), size=Vector3(x=0.4, y=0.4, z=1.0),
                                                    bottom_scale=1.0, top_scale=1.0, color=Color(r=0.1, g=0.1, b=0.1, a=1))])


FLEET_COLOURS = ((0.83, 0.63, 0.09), (0.2, 0.55, 0.85), (0.3, 0.7, 0.3), (0.85, 0.4, 0.6), (0.5, 0.5, 0.5))


def write_run_mcap(df: pd.DataFrame, sc: Scenario, path: Path, bound: pd.DataFrame | None = None, *,
                   scene_every: int = 5) -> Path:
    """``run.mcap`` of a run (``sim.log_schema`` log; see the module docstring); returns its path."""
    t = df["t"].to_numpy()
    relays, sources = relays_in(df.columns), sources_in(df.columns)
    pos = {n: df[[f"{n}.p_x", f"{n}.p_y", f"{n}.p_z"]].to_numpy() for n in relays + sources}
    eul = {n: df[[f"{n}.phi", f"{n}.theta", f"{n}.psi"]].to_numpy() for n in relays + sources}
    ref = {n: df[[f"{n}.pd_x", f"{n}.pd_y", f"{n}.pd_z"]].to_numpy() for n in relays}
    hops = [tuple(c.split(".")[1:]) for c in df.columns if c.startswith("sinr.")]
    for b in sc.base_station_list:
        pos[b.name] = np.repeat(np.array(b.position, float)[None, :], len(t), axis=0)
    tracks = jammer_tracks(sc, t)
    cols = numeric_columns(df)
    values = df[cols].astype(float).to_numpy()
    colour = {n: FLEET_COLOURS[i % len(FLEET_COLOURS)] for i, n in enumerate(relays + sources)}
    best = None
    if bound is not None and "static_position_x" in bound:  # one relay's bound: its best position per instant
        best = np.column_stack([np.interp(t, bound["t"], bound[f"static_position_{a}"]) for a in "xyz"])
    with _mcap_channels(path, sc, cols) as (tf, scene, series):
        for k in range(len(t)):
            ns = _ns(t[k])
            tf.log(FrameTransforms(transforms=[_frame(n, t[k], pos[n][k], eul[n][k]) for n in relays + sources]), log_time=ns)
            series.log({c: float(v) for c, v in zip(cols, values[k], strict=True)}, log_time=ns)
            if k % scene_every:
                continue
            ents = [_vehicle(n, t[k], colour[n]) for n in relays + sources]
            ents += [_marker(f"reference_{n}", t[k], ref[n][k], colour[n], 0.2) for n in relays]
            ents += [_base_station(b.name, t[k], np.asarray(b.position, float)) for b in sc.base_station_list]
            ents += [_link(f"link_{tx}_{rx}", t[k], pos[tx][k], pos[rx][k], float(df[f"sinr.{tx}.{rx}"].iloc[k]))
                     for tx, rx in hops]
            ents += [_marker(f"jammer_{name}", t[k], P[k], (0.9, 0.1, 0.1), 0.4) for name, P in tracks]
            if best is not None:
                ents.append(_marker("bound_best_position", t[k], best[k], (0.1, 0.7, 0.2), 0.25))
            scene.log(SceneUpdate(entities=ents), log_time=ns)
    return Path(path)
