"""The static network problem at one instant solved to global optimality by SCIP (spatial branch and bound with
convex relaxations of products, quotients, powers, logarithms and cosines; ``pyscipopt``): its dual bound is a
certified upper bound on the network's rate, its primal solution a configuration the physics allows.

The problem (``NetworkBoundSolver``'s, written as the functions they are): each relay's position in the workspace
box, at least the separation from the fixed nodes and its route neighbours; its antenna axis a unit vector within
its tilt limit of the vertical (any yaw); each hop's SINR ``Gamma = P_U G_tx G_rx K d^-n / (sigma^2 + sum_j P_j
G_j G_rx,j K d_j^-n)`` with each pattern's gain a function of the cosine ``c`` between its axis and the link
(isotropic: constant; ``sin^n``: ``g (1 - c^2)^(n/2)``; the half-wave dipole: ``G (1 - c^2) = g cos^2(pi c / 2)``,
written ``g (1 + cos(pi c)) / 2`` (SCIP 10's propagation of ``cos(.)^2`` cut off feasible boxes: a relay kept to a
2 m box was declared infeasible), with ``G <= g (1 - c^2)``, which pins ``G`` to the pattern, 0 on the axis); the
objective ``min sum_hops 1 / log2(1 + Gamma)`` (each hop once per route it is on), so the rate is ``B`` over it. Obstacles are left out (a relaxation:
the bound stays an upper bound, looser where an obstacle holds the optimum).

What SCIP cannot express here is refused by ``expressible`` (the cube bound then stays, and says so): a cosine or
tabulated pattern, a path gain that is not ``K d^-n`` (RMa-AV, ray tracing), a jammer aiming at a relay, routes that
may end at several base stations. SCIP's tolerances (feasibility 1e-6, relative gap ``gap``) bound how far its
certificate is exact: its dual bound is a bound on the problem SCIP solved within them.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..models.antenna import DipolePattern, FlippedPattern, IsotropicPattern, SinPowerPattern
from ..models.propagation import PathGain
from ..models.radio import NodePose, RadioScene, link_gain

TAU_MAX = 1e6  # a hop's 1 / log2(1 + Gamma) at most this (a hop this dead: rate below 1e-6 B)


@dataclass(frozen=True)
class GlobalResult:
    """What SCIP proved and found: the certified upper bound on the rate (one instant, ``solve_static``: ``B`` over its
    dual bound; a path, ``solve_path``: on the mean rate), the rate of its best configuration or path by its own model
    (``primal``), that configuration's positions and axes (``(K, 3)``; a path's ``(T, K, 3)``), SCIP's status, its
    relative gap, the seconds it took and its branch-and-bound nodes."""

    upper: float
    primal: float
    positions: np.ndarray
    axes: np.ndarray
    status: str
    gap: float
    seconds: float
    nodes: int


def _pattern(p):
    """``(kind, g, exponent, flipped)`` of a pattern SCIP can be given, else None."""
    flipped = False
    if isinstance(p, FlippedPattern):
        p, flipped = p.inner, True
    if isinstance(p, IsotropicPattern):
        return "iso", p.g_bar, 0.0, flipped
    if isinstance(p, SinPowerPattern):
        return "sin", p.g_bar, float(p.exponent), flipped
    if isinstance(p, DipolePattern):
        return "dipole", p.g_bar, 0.0, flipped
    return None


def expressible(scene: RadioScene) -> str | None:
    """Why SCIP cannot be given this scene's static problem (see the module), None when it can."""
    bad = [n.name for n in scene.nodes if _pattern(n.antenna.pattern) is None]
    bad += [j.name for j in scene.jammers if _pattern(j.pattern) is None]
    if bad:
        return f"the antennas of {bad} are not isotropic, sin^n or a half-wave dipole"
    pg = scene.path_gain
    if type(pg) is not PathGain:  # a subclass (RMa-AV) is not K d^-n
        return f"the path gain ({type(pg).__name__}) is not K d^-n"
    if scene.route_choice:
        return "routes may change in flight (end at several base stations, or skip relays)"
    relays = {n.name for n in scene.nodes if n.role == "relay"}
    if any(j.point_at in relays for j in scene.jammers):
        return "a jammer aims at a relay"
    return None


def _boxes(relays: list[str], lo: np.ndarray, hi: np.ndarray, within: Mapping[str, tuple] | None) -> dict:
    """Each relay's box ``(lo, hi)``: the workspace's, cut to the cube around its ball ``within[r] = (centre, radius)``."""
    out = {}
    for r in relays:
        a, b = np.asarray(lo, float).copy(), np.asarray(hi, float).copy()
        if within is not None and r in within:
            c, rad = np.asarray(within[r][0], float), float(within[r][1])
            a, b = np.maximum(a, c - rad), np.minimum(b, c + rad)
            if np.any(a > b + 1e-12):
                raise ValueError(f"global network bound: relay {r}'s reach does not meet the workspace")
            b = np.maximum(a, b)
        out[r] = (a, b)
    return out


def _instant(m, scene: RadioScene, t: float, poses: Mapping[str, NodePose], relays: list[str], lo: np.ndarray,
             hi: np.ndarray, tilt_limits: Mapping[str, float], separation_m: float, tag: str,
             within: Mapping[str, tuple] | None = None):
    """The static problem at ``t`` added to the SCIP model ``m`` (variables named with ``tag``): each relay's position
    and axis variables, and the expression ``sum_hops uses * 1/log2(1 + Gamma)`` with its most (see the module).
    ``within``: ``{relay: (centre, radius)}``, a ball (m) each such relay is kept in besides the box (a fleet's reach
    from its start: ``NetworkBoundSolver.out_of_reach``'s)."""
    from pyscipopt import cos, log

    box = _boxes(relays, lo, hi, within)
    fixed = {n: p for n, p in poses.items() if n not in relays}
    P = {r: [m.addVar(f"{tag}p_{r}_{i}", lb=box[r][0][i], ub=box[r][1][i]) for i in range(3)] for r in relays}
    if within is not None:
        for r, (c, rad) in within.items():
            if r in P and rad < float(np.linalg.norm(box[r][1] - box[r][0])) / 2:  # the ball cuts the box
                m.addCons(sum((P[r][i] - float(c[i])) ** 2 for i in range(3)) <= float(rad) ** 2)
    node_pat = {n.name: n.antenna.pattern for n in scene.nodes}

    def isotropic(*patterns) -> bool:
        """Whether every one of ``patterns`` is isotropic: its axis and a link's direction change no gain."""
        return all(_pattern(p)[0] == "iso" for p in patterns)

    A: dict[str, list] = {}
    for r in relays:
        if isotropic(node_pat[r]):  # its axis changes no gain: no variables (SCIP branched on the sphere)
            A[r] = [0.0, 0.0, 1.0]
            continue
        cz = math.cos(tilt_limits[r])
        a = [m.addVar(f"{tag}a_{r}_x", lb=-1, ub=1), m.addVar(f"{tag}a_{r}_y", lb=-1, ub=1), m.addVar(f"{tag}a_{r}_z", lb=cz, ub=1)]
        m.addCons(a[0] * a[0] + a[1] * a[1] + a[2] * a[2] == 1)
        A[r] = a

    def pos(n):
        return P[n] if n in P else [float(v) for v in np.asarray(poses[n].position, float)]

    def axis(n):
        return A[n] if n in A else [float(v) for v in np.asarray(poses[n].axis, float)]

    def is_var(n):
        return n in P

    def extent(n) -> tuple[np.ndarray, np.ndarray]:
        if n in box:
            return box[n]
        q = np.asarray(poses[n].position, float)
        return q, q

    ulo, uhi = np.min([b[0] for b in box.values()], axis=0), np.max([b[1] for b in box.values()], axis=0)
    diag2 = float(np.sum((uhi - ulo) ** 2))  # every link's most: the relays' boxes' diagonal, or to the farthest fixed node
    for p in fixed.values():
        q = np.asarray(p.position, float)
        diag2 = max(diag2, float(np.sum(np.maximum(np.abs(q - ulo), np.abs(q - uhi)) ** 2)))
    sep2 = separation_m**2
    count = [0]

    def fresh(name, lb, ub):
        count[0] += 1
        return m.addVar(f"{tag}{name}_{count[0]}", lb=lb, ub=ub)

    def d2_range(a: str | np.ndarray, b: str | np.ndarray) -> tuple[float, float]:
        """The least and most squared length of a link between ``a`` and ``b`` (a node's name or a fixed point): the
        least from their boxes (a relay's at least the separation from any other node), the most every link's
        (``diag2``, or this link's farthest where that is more; each link's own most alone gave SCIP a 35% looser
        bound after 2500 nodes on the jammer test's problem, measured 2026-12-06)."""
        (alo, ahi), (blo, bhi) = [extent(x) if isinstance(x, str) else (np.asarray(x, float),) * 2 for x in (a, b)]
        gap = np.maximum(np.maximum(alo - bhi, blo - ahi), 0.0)
        least = float(np.sum(gap**2))
        if (isinstance(a, str) and a in box) or (isinstance(b, str) and b in box):
            least = max(least, sep2)
        least = max(least, 1e-6)
        far = float(np.sum(np.maximum(np.abs(ahi - blo), np.abs(bhi - alo)) ** 2))  # a jammer beyond diag2's nodes
        return least, max(diag2, far, least)

    def link(a, b, with_length: bool = True):
        """``(delta, d2, d)`` of the link from ``a`` to ``b`` (names or fixed points): its vector (expressions), its
        squared length and length (variables; without ``with_length`` no length: only a pattern's cosine needs it,
        and an unused ``d * d == d2`` is one more nonconvex equality SCIP branches on)."""
        p_from = pos(a) if isinstance(a, str) else [float(v) for v in a]
        p_to = pos(b) if isinstance(b, str) else [float(v) for v in b]
        delta = [p_to[i] - p_from[i] for i in range(3)]
        d2_lo, d2_hi = d2_range(a, b)
        d2 = fresh("d2", d2_lo, d2_hi)
        m.addCons(d2 == delta[0] * delta[0] + delta[1] * delta[1] + delta[2] * delta[2])
        if not with_length:
            return delta, d2, None
        d = fresh("d", math.sqrt(d2_lo), math.sqrt(d2_hi))
        m.addCons(d * d == d2)
        return delta, d2, d

    pg = scene.path_gain

    def gain(pattern, ax, delta, d, sign: float, ax_is_var: bool, delta_is_var: bool):
        """The pattern's gain toward ``sign * delta`` with axis ``ax`` (a variable or a constant)."""
        kind, g, n, flipped = _pattern(pattern)
        if kind == "iso":
            return g
        s = -sign if flipped else sign
        if not (ax_is_var or delta_is_var):  # both ends fixed: a number
            dv = np.asarray([float(v) for v in delta])
            return float(pattern.gain_from_cos(s * float(np.dot(ax, dv)) / float(np.linalg.norm(dv))))
        c = fresh("c", -1.0, 1.0)
        m.addCons(c * d == s * (ax[0] * delta[0] + ax[1] * delta[1] + ax[2] * delta[2]))
        G = fresh("g", 0.0, g)
        if kind == "sin":
            s2 = fresh("s2", 0.0, 1.0)
            m.addCons(s2 == 1 - c * c)
            if n == 2:
                m.addCons(G == g * s2)
            else:
                m.addCons(G == g * s2 ** (0.5 * n))
        else:  # the half-wave dipole, exact (the module)
            m.addCons(G * (1 - c * c) == 0.5 * g * (1 + cos(math.pi * c)))
            m.addCons(G <= g * (1 - c * c))
        return G

    def path(d2):
        """The path gain's length term ``d^-n`` (its scale K is in the powers: every power is over the noise, so SCIP's
        absolute tolerances (1e-6) do not swallow a physical link budget's 1e-13 W)."""
        return 1.0 / d2 if pg.exponent == 2.0 else d2 ** (-0.5 * pg.exponent)

    b = scene.budget
    emitters = [e for e in scene.emitters(t, poses) if e.power > 0.0]
    interference_at: dict[str, object] = {}

    def interference(rx):
        if rx in interference_at:
            return interference_at[rx]
        total: object = 0.0
        for e in emitters:
            ep = [float(v) for v in np.asarray(e.position, float)]
            delta, d2, d = link(ep, rx, not isotropic(e.pattern, node_pat[rx])) if is_var(rx) else (None, None, None)
            if delta is None:  # a fixed receiver: a number
                total = total + e.power / b.noise_power * float(link_gain(e.position, e.axis, e.pattern, poses[rx].position, poses[rx].axis,
                                                          node_pat[rx], pg))
                continue
            gj = gain(e.pattern, [float(v) for v in e.axis], delta, d, 1.0, False, True)
            gr = gain(node_pat[rx], axis(rx), delta, d, -1.0, True, True)
            total = total + e.power * pg.scale / b.noise_power * gj * gr * path(d2)
        interference_at[rx] = total
        return total

    uses: dict[int, int] = {}
    for hops in scene.route_hops():
        for k in hops:
            uses[k] = uses.get(k, 0) + 1
    objective = 0.0
    for k, (tx, rx) in enumerate(scene.hops):
        if k not in uses:
            continue
        moving = is_var(tx) or is_var(rx)
        delta, d2, d = link(tx, rx, not isotropic(node_pat[tx], node_pat[rx]))
        gt = gain(node_pat[tx], axis(tx), delta, d, 1.0, is_var(tx), moving)
        gr = gain(node_pat[rx], axis(rx), delta, d, -1.0, is_var(rx), moving)
        g_most = _pattern(node_pat[tx])[1] * _pattern(node_pat[rx])[1]
        gamma_max = b.tx_power * g_most * pg.scale / d2.getLbOriginal() ** (0.5 * pg.exponent) / b.noise_power
        gamma = fresh("gamma", 0.0, gamma_max)
        m.addCons(gamma * (1.0 + interference(rx)) <= b.tx_power * pg.scale / b.noise_power * gt * gr * path(d2))
        tau = fresh("tau", 1.0 / math.log2(1.0 + gamma_max), TAU_MAX)
        m.addCons(tau * log(1 + gamma) >= math.log(2.0))
        objective = objective + uses[k] * tau
    if sep2 > 0:  # the separation from every fixed node (a route neighbour's: the link's least length above)
        for r in relays:
            for p in fixed.values():
                q = np.asarray(p.position, float)
                m.addCons(sum((P[r][i] - float(q[i])) ** 2 for i in range(3)) >= sep2)
    return P, A, objective, TAU_MAX * sum(uses.values())


def _model(time_limit_s: float, gap: float, seed: int, node_limit: int | None = None):
    from pyscipopt import Model

    m = Model("network")
    if node_limit is not None:  # a limit that does not depend on the machine's speed (tests)
        m.setParam("limits/nodes", int(node_limit))
    m.hideOutput()
    m.setParam("limits/time", float(time_limit_s))
    m.setParam("limits/gap", float(gap))
    m.setParam("randomization/randomseedshift", int(seed))
    return m


def _optimize(m) -> float:
    """Run SCIP on ``m``; the seconds it took."""
    begun = time.perf_counter()
    m.optimize()
    return time.perf_counter() - begun


def _best(m, Ps: list[dict], As: list[dict], relays: list[str]) -> tuple[np.ndarray, np.ndarray, float]:
    """SCIP's best solution: the relays' positions and unit axes ``(T, K, 3)`` at each instant's variables (``Ps``,
    ``As``) and its objective's value; NaNs and 0 without one."""
    if m.getNSols() == 0:
        return np.full((len(Ps), len(relays), 3), np.nan), np.full((len(As), len(relays), 3), np.nan), 0.0
    sol = m.getBestSol()
    assert sol is not None
    positions = np.array([[[sol[v] for v in P[r]] for r in relays] for P in Ps])
    axes = np.array([[[v if isinstance(v, float) else sol[v] for v in A[r]] for r in relays] for A in As])
    return positions, axes / np.linalg.norm(axes, axis=2, keepdims=True), float(m.getSolObjVal(sol))


def solve_static(scene: RadioScene, t: float, poses: Mapping[str, NodePose], relays: list[str], lo, hi,
                 tilt_limits: Mapping[str, float], separation_m: float = 0.0, *, time_limit_s: float = 60.0,
                 gap: float = 1e-3, seed: int = 0, node_limit: int | None = None,
                 within: Mapping[str, tuple] | None = None) -> GlobalResult:
    """The static problem at ``t`` (see the module) with the fixed nodes and sources at ``poses``; ``relays`` in the
    result's order, each in ``[lo, hi]`` (m) within ``tilt_limits`` (rad); with ``within`` (``{relay: (centre,
    radius)}``, m) each such relay also in that ball (where a fleet from its starts can be at ``t``). Stops at
    ``gap`` (relative, SCIP's) or ``time_limit_s``; the upper bound is SCIP's dual bound either way. ``node_limit``: SCIP's branch-and-bound nodes
    at most (its work the same on any machine)."""
    why = expressible(scene)
    if why is not None:
        raise ValueError(f"global network bound: {why}")
    m = _model(time_limit_s, gap, seed, node_limit)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    P, A, objective, most = _instant(m, scene, t, poses, relays, lo, hi, tilt_limits, separation_m, "", within)
    b = scene.budget
    z = m.addVar("objective", lb=0.0, ub=most)
    m.addCons(z >= objective)
    m.setObjective(z, "minimize")
    seconds = _optimize(m)
    dual = m.getDualbound()
    positions, axes, objective_value = _best(m, [P], [A], relays)
    primal = b.bandwidth / objective_value if objective_value > 0 else 0.0
    return GlobalResult(b.bandwidth / dual if dual > 0 else math.inf, primal, positions[0], axes[0], str(m.getStatus()),
                        float(m.getGap()), seconds, int(m.getNNodes()))


def solve_path(scene: RadioScene, times, poses: list[Mapping[str, NodePose]], relays: list[str], lo, hi,
               tilt_limits: Mapping[str, float], starts: Mapping[str, np.ndarray], max_speed_m_s: float,
               separation_m: float = 0.0, *, time_limit_s: float = 60.0, gap: float = 1e-3, seed: int = 0) -> GlobalResult:
    """The time-coupled problem over ``times`` (s; the sources at ``poses[i]`` then): every instant's static problem
    (``solve_static``), each relay at ``times[i]`` within ``max_speed_m_s * times[i]`` of its start (at it at 0) and
    within ``max_speed_m_s * dt`` of where it was the instant before; the objective the mean of the instants' rates.
    Its dual bound is an upper bound on the mean rate (over these instants) of every fleet path from the starts that
    keeps the speed limit (the acceleration limit and the axis's lean with the path's thrust are left out: a
    relaxation); its primal a path within those limits. Small K and few instants: SCIP's work grows fast with both."""
    why = expressible(scene)
    if why is not None:
        raise ValueError(f"global network path bound: {why}")
    times = np.asarray(times, float)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m = _model(time_limit_s, gap, seed)
    b = scene.budget
    Ps: list[dict] = []
    As: list[dict] = []
    rates: list = []
    for i, t in enumerate(times):
        reach = {r: (np.asarray(starts[r], float), max_speed_m_s * float(t)) for r in relays}
        P, A, objective, most = _instant(m, scene, float(t), poses[i], relays, lo, hi, tilt_limits, separation_m, f"t{i}_",
                                         reach)
        total = m.addVar(f"t{i}_sum", lb=1e-12, ub=most)
        m.addCons(total >= objective)
        rate = m.addVar(f"t{i}_rate", lb=0.0, ub=b.bandwidth * 1e12)
        m.addCons(rate * total <= b.bandwidth)
        if i > 0:
            step = max_speed_m_s * float(t - times[i - 1])
            for r in relays:
                m.addCons(sum((P[r][k] - Ps[-1][r][k]) ** 2 for k in range(3)) <= step**2)
        Ps.append(P)
        As.append(A)
        rates.append(rate)
    m.setObjective(sum(rates) / len(times), "maximize")
    seconds = _optimize(m)
    positions, axes, primal = _best(m, Ps, As, relays)
    return GlobalResult(float(m.getDualbound()), primal, positions, axes, str(m.getStatus()), float(m.getGap()), seconds,
                        int(m.getNNodes()))
