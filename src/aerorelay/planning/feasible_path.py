"""The best relay path at exactly the speed limit: a continuous refinement of the grid bound's path.

The grid bound (``planning/bound.py``) lets each step reach any cell within ``max_speed * dt +
grid / 2``: its path may fly faster than ``max_speed`` (a diagonal step at 1 m/s on a 0.5 m /
0.5 s grid is 1.41 m/s) and so overstates what a relay at ``max_speed`` can reach. Here the path
is a flyable one: positions ``p_k`` (m, world) at the bound's times, from the relay's own start,
with ``|p_(k+1) - p_k| <= max_speed * dt`` (Euclidean) and, with ``max_accel``, second
differences ``<= max_accel * dt^2`` from rest (the first move ``<= max_accel * dt^2 / 2``),
inside the workspace box, each with an antenna axis the platform can hold in hover (tilt <=
``hover_tilt_limit``, any azimuth: yaw free; vertical only for a coplanar platform) and, on a
tilted platform, hold while it flies the path: within the same limit of the thrust direction
the path's acceleration needs (``thrust_directions``; a tilted multirotor's force leaves its
body z by at most about its hover tilt limit, so a relay braking at 4 m/s^2 (22 deg) cannot
hold its antenna tilted 18 deg the other way). The true capacity of the radio scene (eq. 5-9, on CasADi
symbols) at each sample is maximized by IPOPT from the grid path pulled back to the speed limit:
its mean (``kind="mean"``) or, through an epigraph variable, its minimum (``"maxmin"``). The
result is a path a relay at ``max_speed`` could fly (attitude changes within the samples free, capacity evaluated at
the samples), so its value is a *lower* estimate of the best path at that speed, where the grid
bound is an upper one: the best path lies between the two.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..models.axes import tilted_axes
from ..models.geometry import clip_norm
from ..models.radio import NodePose

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FeasiblePath:
    """Capacities ``(T,)`` (normalized, B = 1), positions ``(T, 3)`` (m, world), antenna axes
    ``(T, 3)`` (unit, world) and IPOPT's return status."""

    capacity: np.ndarray
    position: np.ndarray
    axis: np.ndarray
    status: str


@dataclass(frozen=True)
class FleetPath:
    """A flyable fleet path: the network's capacities ``(T,)`` (the capacity function's units), each
    relay's positions ``(T, K, 3)`` (m, world) and antenna axes ``(T, K, 3)`` (unit, world), and
    IPOPT's return status."""

    capacity: np.ndarray
    position: np.ndarray
    axis: np.ndarray
    status: str


def speed_limited(path: np.ndarray, start: np.ndarray, step_m: float, dv_m: float | None = None) -> np.ndarray:
    """``path (T, 3)`` chased from ``start`` (at rest) moving at most ``step_m`` per sample and,
    with ``dv_m``, changing the move by at most ``dv_m`` per sample (a flyable first guess)."""
    out = np.empty_like(np.asarray(path, float))
    p, move = np.asarray(start, float).copy(), np.zeros(3)
    for k, target in enumerate(path):
        if k > 0:
            want = clip_norm(target - p, step_m)
            # the ball |move| <= step_m is convex: projecting onto it never enlarges the change;
            # from rest the first move is at most dv_m / 2 (a dt^2 / 2)
            dv = None if dv_m is None else (0.5 * dv_m if k == 1 else dv_m)
            move = want if dv is None else clip_norm(move + clip_norm(want - move, dv), step_m)
            p = p + move
        out[k] = p
    return out


def _path_accelerations(P, dt: float) -> list:
    """Accelerations (m/s^2) of a sampled path ``P (3, T)`` (CasADi), one per sample: at the start
    from rest ``2 (p_1 - p_0) / dt^2``, then second differences / dt^2, the last sample repeating
    the one before."""
    T = P.shape[1]
    acc = [ca.SX.zeros(3) if T < 2 else 2.0 * (P[:, 1] - P[:, 0]) / dt**2]
    for k in range(1, T):
        j = min(k, T - 2)
        acc.append((P[:, j + 1] - 2 * P[:, j] + P[:, j - 1]) / dt**2 if j >= 1 else acc[0])
    return acc


def path_accelerations(T: int, dt: float) -> ca.Function:
    """CasADi function positions ``(3, T)`` (m) -> accelerations ``(3, T)`` (m/s^2), ``_path_accelerations``."""
    P = ca.SX.sym("p", 3, T)
    return ca.Function("path_accels", [P], [ca.horzcat(*_path_accelerations(P, dt))])


def thrust_directions(T: int, dt: float, gravity: float) -> ca.Function:
    """CasADi function positions ``(3, T)`` -> unit thrust directions ``(3, T)`` ``(a + g e3)/|.|``
    of the path's accelerations (``_path_accelerations``): where the platform's body z must lean
    for the path to be flown (eq. 20's ``rho_d``)."""
    P = ca.SX.sym("p", 3, T)
    f = path_accelerations(T, dt)(P) + ca.repmat(ca.DM([0.0, 0.0, gravity]), 1, T)
    return ca.Function("thrust_dirs", [P], [f / ca.repmat(ca.sqrt(ca.sum1(f**2)), 3, 1)])


def fleet_thrust_directions(P: np.ndarray, dt: float, gravity: float) -> np.ndarray:
    """``(T, K, 3)``: the unit direction each relay's thrust points to fly its sampled path ``P`` ``(T, K, 3)``
    (m) ``dt`` (s) apart: ``path_accelerations`` plus gravity, normalized (numpy)."""
    accel = path_accelerations(P.shape[0], dt)
    out = np.empty_like(P)
    for k in range(P.shape[1]):
        f = np.asarray(accel(P[:, k].T)).T + np.array([0.0, 0.0, gravity])
        out[:, k] = f / np.linalg.norm(f, axis=1, keepdims=True)
    return out


def best_feasible_path(landscape, times: np.ndarray, guess: np.ndarray, start: np.ndarray, lo, hi,
                       max_speed: float, max_tilt: float, kind: str = "mean", max_iter: int = 300,
                       max_accel: float | None = None) -> FeasiblePath:
    """The best flyable relay path (see the module docstring) near ``guess (T, 3)`` (the grid path):
    ``best_feasible_fleet_path`` for a fleet of one.

    ``landscape``: a ``CapacityLandscape`` (its scene, source trajectory and jammers); ``times``
    (s) evenly spaced; ``start`` the relay's start (m); ``lo``/``hi`` the workspace box (m);
    ``max_speed`` m/s; ``max_tilt`` rad (0: a coplanar platform, axis vertical); ``max_accel``
    m/s^2 (None: unbounded), on the second differences, from rest at the start."""
    if kind not in ("mean", "maxmin"):
        raise ValueError(f"kind must be 'mean' or 'maxmin', got {kind!r}")
    T = len(times)
    if guess.shape != (T, 3):
        raise ValueError(f"guess: expected ({T}, 3) positions, got {guess.shape}")
    dt = float(times[1] - times[0]) if T > 1 else 1.0
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    start = np.clip(np.asarray(start, float), lo, hi)
    dv = None if max_accel is None else max_accel * dt**2
    p0 = np.clip(speed_limited(guess, start, max_speed * dt, dv), lo, hi)
    a_guess = None
    if max_tilt > 0.0:
        dirs = np.asarray(thrust_directions(T, dt, landscape.gravity)(p0.T))
        a_guess = _best_axes(landscape, times, p0, max_tilt, dirs)[:, None, :]
    scene = landscape.scene

    def capacity(t: float, positions: list, axes: list):
        poses = {landscape.relay_name: NodePose(positions[0], axes[0]), landscape.source_name: landscape.source_pose(t)}
        return scene.evaluate(t, poses, jammer_powers=landscape.silent).capacity

    fleet = best_feasible_fleet_path(capacity, times, p0[:, None, :], lo, hi, max_speed, [max_tilt], landscape.gravity,
                                     kind, max_iter, max_accel, a_guess)
    return FeasiblePath(fleet.capacity, fleet.position[:, 0], fleet.axis[:, 0], fleet.status)


def best_feasible_fleet_path(capacity, times: np.ndarray, p0: np.ndarray, lo, hi, max_speed: float,
                             max_tilts, gravity: float, kind: str = "mean", max_iter: int = 300,
                             max_accel: float | None = None, a0: np.ndarray | None = None, separation_m: float = 0.0,
                             fixed: np.ndarray | None = None) -> FleetPath:
    """The best flyable path of K relays jointly (IPOPT, the module docstring's limits for every relay)
    from the flyable first guess ``p0 (T, K, 3)`` (m, world; ``p0[0]`` the relays' starts, kept).

    ``capacity(t, positions, axes)``: the network's capacity (CasADi) at ``t`` (s) with relay ``k`` at
    ``positions[k]`` (3-vector, m) holding ``axes[k]`` (unit, world); ``max_tilts`` each relay's hover
    tilt limit (rad; 0: coplanar, axis vertical); ``a0 (T, K, 2)`` the tilted relays' first (tilt,
    azimuth) (rad; holdable along ``p0``); with ``separation_m`` > 0 every two relays and every relay
    and each of ``fixed (T, F, 3)`` (m: the sources' and fixed nodes' positions at each sample) at
    least that far apart after the start. A solve whose path breaks a limit, or scores below the first
    guess, reports the first guess."""
    T, K = p0.shape[:2]
    dt = float(times[1] - times[0]) if T > 1 else 1.0
    step = max_speed * dt
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    tilts = [float(m) for m in max_tilts]
    P = [ca.SX.sym("p" if K == 1 else f"p{k}", 3, T) for k in range(K)]
    A = {k: ca.SX.sym("a" if K == 1 else f"a{k}", 2, T) for k in range(K) if tilts[k] > 0.0}
    tilted = list(A)
    if tilted and (a0 is None or a0.shape != (T, K, 2)):
        raise ValueError(f"a0: expected ({T}, {K}, 2) first (tilt, azimuth) angles for the tilted relays")
    dirs = thrust_directions(T, dt, gravity)
    axes_sym = [[tilted_axes(A[k][0, i], A[k][1, i]) if k in A else ca.DM([0.0, 0.0, 1.0]) for i in range(T)]
                for k in range(K)]
    C = ca.vertcat(*[capacity(float(t), [P[k][:, i] for k in range(K)], [axes_sym[k][i] for k in range(K)])
                     for i, t in enumerate(times)])
    inputs = P + [A[k] for k in tilted]
    f_cap = ca.Function("caps", inputs, [C])
    AX = [ca.horzcat(*axes_sym[k]) for k in range(K)]
    f_axes = ca.Function("axes", inputs, AX)

    def args(pos: np.ndarray, ang) -> list:
        return [pos[:, k].T for k in range(K)] + [ang[:, k].T for k in tilted]

    c_guess = np.asarray(f_cap(*args(p0, a0))).ravel()
    scale = 1.0 / max(float(np.mean(c_guess)), 1e-12)
    # decision vector: every relay's positions, the tilted relays' axis angles, (maxmin) the floor s
    x = [ca.vec(P[k]) for k in range(K)] + [ca.vec(A[k]) for k in tilted]
    s = ca.SX.sym("s") if kind == "maxmin" else None
    if s is not None:
        x.append(s)
    g = [ca.vertcat(*[ca.sumsqr(P[k][:, i + 1] - P[k][:, i]) for k in range(K) for i in range(T - 1)]) / step**2]
    lbg, ubg = [np.full(K * (T - 1), -np.inf)], [np.ones(K * (T - 1))]
    if max_accel is not None and T > 1:  # from rest: |p_1 - p_0| <= a dt^2 / 2, then |p_(k+1) - 2 p_k + p_(k-1)| <= a dt^2
        g.append(ca.vertcat(*[ca.sumsqr(a) for k in range(K) for a in _path_accelerations(P[k], dt)[:T - 1]]) / max_accel**2)
        lbg.append(np.full(K * (T - 1), -np.inf))
        ubg.append(np.ones(K * (T - 1)))
    for k in tilted:  # each axis within the tilt limit of the thrust the path needs there
        g.append(ca.sum1(AX[k] * dirs(P[k])).T)
        lbg.append(np.full(T, np.cos(tilts[k])))
        ubg.append(np.full(T, np.inf))
    if separation_m > 0.0 and T > 1:  # after the start: every pair of relays, every relay and every fixed node
        gaps = [ca.sumsqr(P[a][:, i] - P[b][:, i]) for i in range(1, T) for a in range(K) for b in range(a + 1, K)]
        if fixed is not None:
            gaps += [ca.sumsqr(P[a][:, i] - fixed[i, f]) for i in range(1, T) for a in range(K) for f in range(fixed.shape[1])]
        if gaps:
            g.append(ca.vertcat(*gaps) / separation_m**2)
            lbg.append(np.ones(len(gaps)))
            ubg.append(np.full(len(gaps), np.inf))
    if s is not None:
        g.append(C * scale - s)
        lbg.append(np.zeros(T))
        ubg.append(np.full(T, np.inf))
        objective = -s
    else:
        objective = -ca.sum1(C) * scale / T
    lbx, ubx = [], []
    for k in range(K):
        lbx_p, ubx_p = np.tile(lo, T), np.tile(hi, T)
        lbx_p[:3], ubx_p[:3] = p0[0, k], p0[0, k]  # the relay's own start
        lbx.append(lbx_p)
        ubx.append(ubx_p)
    lbx += [np.tile([0.0, -np.inf], T) for _ in tilted]
    ubx += [np.tile([tilts[k], np.inf], T) for k in tilted]
    x0 = [p0[:, k].ravel() for k in range(K)] + [np.ravel(a0[:, k]) for k in tilted]  # type: ignore[index]
    if s is not None:
        lbx.append(np.array([-np.inf]))
        ubx.append(np.array([np.inf]))
        x0.append(np.array([float(np.min(c_guess)) * scale]))
    nlp = {"x": ca.vertcat(*x), "f": objective, "g": ca.vertcat(*g)}
    solver = ca.nlpsol("feasible_path", "ipopt", nlp, {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False,
                                                        "ipopt.max_iter": max_iter, "ipopt.tol": 1e-8,
                                                        "ipopt.constr_viol_tol": 1e-9})
    sol = solver(x0=np.concatenate([np.ravel(v) for v in x0]), lbx=np.concatenate([np.ravel(v) for v in lbx]),
                 ubx=np.concatenate([np.ravel(v) for v in ubx]), lbg=np.concatenate(lbg), ubg=np.concatenate(ubg))
    status = str(solver.stats()["return_status"])
    xs = np.asarray(sol["x"]).ravel()
    pos = np.stack([xs[3 * T * k:3 * T * (k + 1)].reshape(T, 3) for k in range(K)], axis=1)
    ang = None
    if tilted:
        ang = np.zeros((T, K, 2))
        for j, k in enumerate(tilted):
            ang[:, k] = xs[3 * T * K + 2 * T * j:3 * T * K + 2 * T * (j + 1)].reshape(T, 2)
    pos, ang = _fleet_flyable_or_guess(pos, ang, p0, a0, lo, hi, step, tilts, status, max_accel, dt, f_axes, dirs,
                                       separation_m, fixed)
    if pos is p0:
        status += " (outside the limits: first guess reported)"
    cap = np.asarray(f_cap(*args(pos, ang))).ravel()
    value = (lambda c: float(np.mean(c))) if kind == "mean" else (lambda c: float(np.min(c)))
    if value(cap) < value(c_guess):  # a local solve may end below its start: never report worse
        pos, ang, cap, status = p0, a0, c_guess, status + " (first guess kept: better)"
    out = f_axes(*args(pos, ang))
    axes = np.stack([np.asarray(out[k] if K > 1 else out).T for k in range(K)], axis=1)
    return FleetPath(cap, pos, axes, status)


def _fleet_flyable_or_guess(pos, ang, p0, a0, lo, hi, step, tilts, status, max_accel, dt, f_axes, dirs, separation_m, fixed):
    """``_flyable_or_guess`` for every relay (its speed, box, acceleration, tilt and lean) and, with a
    separation, every pair's and every relay's distance to the fixed nodes after the start: IPOPT's
    fleet path, or the first guess when any relay's or pair's check fails."""
    T, K = pos.shape[:2]
    tilted = [k for k in range(K) if tilts[k] > 0.0]
    accels = path_accelerations(T, dt)
    accel_ratio = None if max_accel is None else (  # the limited samples' |a| / max_accel, as constrained
        lambda q: np.linalg.norm(np.asarray(accels(q.T))[:, :T - 1], axis=0) / max_accel)
    finite = bool(np.all(np.isfinite(pos))) and (ang is None or bool(np.all(np.isfinite(ang))))
    axes_all = None
    if finite and tilted:
        out = f_axes(*([pos[:, k].T for k in range(K)] + [ang[:, k].T for k in tilted]))
        axes_all = [np.asarray(out[k] if K > 1 else out) for k in range(K)]
    kept = np.empty_like(pos)
    for k in range(K):
        lean = None if axes_all is None or k not in tilted else (
            lambda q, a, k=k: np.asarray(ca.sum1(ca.DM(axes_all[k]) * dirs(q.T))).ravel())
        a_k, a0_k = (None, None) if k not in tilted else (ang[:, k], a0[:, k])
        first = p0[:, k]
        got, _ = _flyable_or_guess(pos[:, k], a_k, first, a0_k, lo, hi, step, tilts[k], status, accel_ratio, lean)
        if got is first:
            return p0, a0
        kept[:, k] = got  # clipped into the box (within 1e-6 of it)
    pos = kept
    if separation_m > 0.0 and T > 1:
        gaps = [np.linalg.norm(pos[1:, a] - pos[1:, b], axis=-1) for a in range(K) for b in range(a + 1, K)]
        if fixed is not None:
            gaps += [np.linalg.norm(pos[1:, a, None] - fixed[1:], axis=-1).ravel() for a in range(K)]
        closest = min((float(np.min(g)) for g in gaps if np.size(g)), default=np.inf)
        if closest < separation_m * (1 - 1e-6):
            log.warning("feasible fleet path: IPOPT returned %s with two vehicles %.3f m apart (separation %.3f m); the "
                        "first guess is reported", status, closest, separation_m)
            return p0, a0
    return pos, ang


def _flyable_or_guess(pos, ang, p0, a0, lo, hi, step, max_tilt, status, accel_ratio=None, lean_cos=None):
    """IPOPT's path if it is flyable (speed, box, tilt within 1e-6 relative; with ``accel_ratio(pos)``,
    the limited samples' acceleration over the limit, that <= 1; with ``lean_cos(pos, ang)``, each
    axis's cosine to the path's thrust direction, that within the tilt limit), else the first
    guess (always flyable): a failed solve never reports a path the relay could not fly."""
    moves = np.diff(np.vstack([pos[:1], pos]), axis=0)  # from rest
    checks = {
        "finite": bool(np.all(np.isfinite(pos))) and (ang is None or bool(np.all(np.isfinite(ang)))),
        "box": bool(np.all(pos >= lo - 1e-6) and np.all(pos <= hi + 1e-6)),
        "speed": bool(np.all(np.linalg.norm(moves, axis=1) <= step * (1 + 1e-6))),
        "tilt": ang is None or bool(np.all(ang[:, 0] <= max_tilt + 1e-9) and np.all(ang[:, 0] >= -1e-9)),
    }
    if checks["finite"] and accel_ratio is not None:
        checks["acceleration"] = bool(np.all(accel_ratio(pos) <= 1 + 1e-6))
    if checks["finite"] and ang is not None and lean_cos is not None:
        checks["lean"] = bool(np.all(lean_cos(pos, ang) >= np.cos(max_tilt) - 1e-7))
    failed = [name for name, ok in checks.items() if not ok]
    if not failed:
        return np.clip(pos, lo, hi), ang
    log.warning("feasible path: IPOPT returned %s with a path outside the limits (%s); the speed-limited grid path is "
                "reported", status, ", ".join(failed))
    return p0, a0


def leaning_capacity(landscape, times: np.ndarray, positions: np.ndarray, axes: np.ndarray, max_tilt: float) -> np.ndarray:
    """Best capacity at each sample of a path ``positions (T, 3)`` (m) over the candidate ``axes
    (K, 3)`` a platform can point there: on a tilted one (``max_tilt`` > 0 rad) those within
    ``max_tilt`` of the thrust direction the path's acceleration needs (``thrust_directions``; the
    nearest to it where none is), on a coplanar one every candidate (its axis is vertical)."""
    caps = _sample_capacities(landscape, times, positions, axes)
    if max_tilt <= 0.0 or len(times) < 2:
        return caps.max(axis=1)
    dirs = np.asarray(thrust_directions(len(times), float(times[1] - times[0]), landscape.gravity)(positions.T))
    return caps[np.arange(len(times)), _best_held_axis(caps, axes @ dirs, max_tilt)]


def _sample_capacities(landscape, times: np.ndarray, positions: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """``(T, K)``: the capacity at each sample's position ``positions (T, 3)`` with each of ``axes (K, 3)``."""
    return np.array([landscape.capacity(float(t), positions[k][None], axes)[0] for k, t in enumerate(times)])


def _best_held_axis(caps: np.ndarray, cos: np.ndarray, max_tilt: float) -> np.ndarray:
    """Per sample, the index of the best axis (``caps (T, K)``) among those within ``max_tilt`` rad
    of the path's thrust direction (``cos (K, T)``: each axis's cosine to it), the nearest where none is."""
    held = np.where((cos >= np.cos(max_tilt) - 1e-12).T, caps, -np.inf)
    return np.where(np.isfinite(held).any(axis=1), np.argmax(held, axis=1), np.argmax(cos, axis=0))


def _best_axes(landscape, times, positions, max_tilt: float, dirs: np.ndarray, n_tilt: int = 6, n_az: int = 24) -> np.ndarray:
    """(tilt, azimuth) of the best axis of a coarse cone at each sample position among those
    within ``max_tilt`` of the path's thrust direction ``dirs (3, T)`` (the nearest to it if none is)."""
    grid = np.meshgrid(np.linspace(0.0, max_tilt, n_tilt), np.linspace(0.0, 2 * np.pi, n_az, endpoint=False), indexing="ij")
    tilt, az = grid[0].ravel(), grid[1].ravel()
    axes = tilted_axes(tilt, az)
    caps = _sample_capacities(landscape, times, positions, axes)
    j = _best_held_axis(caps, axes @ dirs, max_tilt)
    return np.column_stack([tilt[j], az[j]])
