"""End-to-end capacity at M relay positions x K antenna axes in one compiled call (the capacity
planner's candidate scoring).

The same channel as ``RadioScene.relay_grid``: the scene is evaluated once on CasADi symbols
(``models.radio``, eq. 5-9), mapped over the M x K grid, generated to C and compiled
(``store.codegen``; CasADi's virtual machine if there is no compiler), and called through
CasADi's buffer interface, so a call costs the arithmetic and not numpy's per-operation overhead
(27 x 15 poses: 0.08 ms against 0.32 ms for the numpy evaluation, measured 2026-12-02). The one
difference is the symbolic dipole's regularization of sin^2 (``SYMBOLIC_AXIS_EPS``): relative
1e-6 / sin^2 per gain, a few percent within a fraction of a degree of a null, < 2e-3 where every
link is > 3 deg off the relay's axis (the comparison test).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..models.radio import NodePose, RadioScene
from ..store.codegen import BufferedCall, compiled


class CompiledRelayGrid:
    """``grid(positions (M, 3), axes (K, 3), source_pose, jammer_positions (nJ, 3), jammer_powers
    (nJ,), others=())`` -> capacity ``(M, K)``: relay positions m (world) x relay antenna axes (unit, world),
    powers W. The scene's other moving nodes are the source and ``moving`` (their poses given, ``others`` in
    that order: a fleet's other sources and relays); fixed nodes as placed."""

    def __init__(self, scene: RadioScene, n_positions: int, n_axes: int, *, source: str, relay: str | None = None,
                 moving: tuple[str, ...] = ()):
        """``relay``: the node on the grid (default: the scene's first relay)."""
        self.m, self.k, self.nj, self.no = int(n_positions), int(n_axes), len(scene.jammers), len(moving)
        relay = relay or scene.name_of("relay")
        self._call = BufferedCall(compiled(self._grid_function(scene, source, relay, tuple(moving)), "relay_grid"))
        self._z = self._call.arg

    def _grid_function(self, scene: RadioScene, source: str, relay: str, moving: tuple[str, ...]) -> ca.Function:
        """``z = (vec(P) (3M), vec(B) (3K), p2, b2, vec(pJ) (3 nJ), P_J, (p, b) of each of moving)`` -> capacities,
        index ``m K + k``."""
        nj, m, k, no = self.nj, self.m, self.k, len(moving)
        p, b, rest = ca.SX.sym("p", 3), ca.SX.sym("b", 3), ca.SX.sym("rest", 6 + 4 * nj + 6 * no)
        pj = [rest[6 + 3 * i: 9 + 3 * i] for i in range(nj)]
        o = 6 + 4 * nj
        poses = {relay: NodePose(p, b), source: NodePose(rest[0:3], rest[3:6])}
        poses |= {name: NodePose(rest[o + 6 * i: o + 6 * i + 3], rest[o + 6 * i + 3: o + 6 * i + 6]) for i, name in enumerate(moving)}
        state = scene.evaluate(0.0, poses, jammer_positions=pj, jammer_powers=[rest[6 + 3 * nj + i] for i in range(nj)])
        one = ca.Function("relay_capacity", [p, b, rest], [state.capacity])
        z = ca.MX.sym("z", 3 * m + 3 * k + 6 + 4 * nj + 6 * no)
        n = m * k
        positions = ca.mtimes(ca.reshape(z[:3 * m], 3, m), ca.DM(np.kron(np.eye(m), np.ones((1, k)))))
        axes = ca.repmat(ca.reshape(z[3 * m:3 * (m + k)], 3, k), 1, m)
        grid = one.map(n, "serial")(positions, axes, ca.repmat(z[3 * (m + k):], 1, n))
        return ca.Function("relay_grid", [z], [ca.densify(grid)])

    def __call__(self, positions, axes, source_pose: NodePose, jammer_positions, jammer_powers,
                 others: tuple[NodePose, ...] = ()) -> np.ndarray:
        P, B = np.asarray(positions, float), np.asarray(axes, float)
        pj = np.asarray(jammer_positions, float).reshape(-1, 3)
        PJ = np.asarray(jammer_powers, float).ravel()
        if P.shape != (self.m, 3) or B.shape != (self.k, 3) or pj.shape[0] != self.nj or PJ.shape != (self.nj,) \
                or len(others) != self.no:
            raise ValueError(f"relay grid: built for {self.m} positions, {self.k} axes, {self.nj} jammer(s) and {self.no} "
                             f"other moving node(s), got positions {P.shape}, axes {B.shape}, jammer positions {pj.shape}, "
                             f"powers {PJ.shape}, {len(others)} other(s)")
        o = 3 * (self.m + self.k)
        self._z[:3 * self.m], self._z[3 * self.m:o] = P.ravel(), B.ravel()
        self._z[o:o + 3], self._z[o + 3:o + 6] = source_pose.position, source_pose.axis
        self._z[o + 6:o + 6 + 3 * self.nj], self._z[o + 6 + 3 * self.nj:o + 6 + 4 * self.nj] = pj.ravel(), PJ
        q = o + 6 + 4 * self.nj
        for i, pose in enumerate(others):
            self._z[q + 6 * i:q + 6 * i + 3], self._z[q + 6 * i + 3:q + 6 * i + 6] = pose.position, pose.axis
        C = self._call().reshape(self.m, self.k)
        # a jammer on a receiver: the numpy evaluation's infinite interference, capacity 0
        return np.where(np.isfinite(C), C, 0.0)


class CompiledConfigurations:
    """``rates(positions (n, K, 3), axes (n, K, 3), sources, jammer_positions (nJ, 3), jammer_powers (nJ,))`` ->
    the network's capacity ``(n,)`` of ``n`` configurations of the fleet ``relays`` (m, unit, world) with the
    ``source_names``' poses ``sources`` (in that order) in one compiled call (a fleet planner's joint moves)."""

    def __init__(self, scene: RadioScene, relays: tuple[str, ...], source_names: tuple[str, ...], n_configs: int):
        self.relays, self.sources, self.n, self.nj = tuple(relays), tuple(source_names), int(n_configs), len(scene.jammers)
        K, ns, nj = len(self.relays), len(self.sources), self.nj
        cfg, rest = ca.SX.sym("cfg", 6 * K), ca.SX.sym("rest", 6 * ns + 4 * nj)
        poses = {r: NodePose(cfg[6 * k: 6 * k + 3], cfg[6 * k + 3: 6 * k + 6]) for k, r in enumerate(self.relays)}
        poses |= {s: NodePose(rest[6 * i: 6 * i + 3], rest[6 * i + 3: 6 * i + 6]) for i, s in enumerate(self.sources)}
        o = 6 * ns
        state = scene.evaluate(0.0, poses, jammer_positions=[rest[o + 3 * i: o + 3 * i + 3] for i in range(nj)],
                               jammer_powers=[rest[o + 3 * nj + i] for i in range(nj)])
        one = ca.Function("configuration_capacity", [cfg, rest], [state.capacity])
        z = ca.MX.sym("z", 6 * K * self.n + 6 * ns + 4 * nj)
        rates = one.map(self.n, "serial")(ca.reshape(z[:6 * K * self.n], 6 * K, self.n), ca.repmat(z[6 * K * self.n:], 1, self.n))
        self._call = BufferedCall(compiled(ca.Function("configuration_rates", [z], [ca.densify(rates)]), "configuration_rates"))
        self._z = self._call.arg

    def __call__(self, positions, axes, sources: tuple[NodePose, ...], jammer_positions, jammer_powers) -> np.ndarray:
        P, B = np.asarray(positions, float), np.asarray(axes, float)
        K = len(self.relays)
        if P.shape != (self.n, K, 3) or B.shape != (self.n, K, 3) or len(sources) != len(self.sources):
            raise ValueError(f"configurations: built for {self.n} configurations of {K} relays and {len(self.sources)} "
                             f"source(s), got positions {P.shape}, axes {B.shape}, {len(sources)} source(s)")
        m = 6 * K * self.n
        self._z[:m] = np.concatenate([P, B], axis=2).ravel()  # per configuration, per relay: p, b
        for i, pose in enumerate(sources):
            self._z[m + 6 * i: m + 6 * i + 3], self._z[m + 6 * i + 3: m + 6 * i + 6] = pose.position, pose.axis
        o = m + 6 * len(self.sources)
        self._z[o: o + 3 * self.nj] = np.asarray(jammer_positions, float).reshape(-1, 3).ravel()
        self._z[o + 3 * self.nj:] = np.asarray(jammer_powers, float).ravel()
        C = self._call().copy()
        return np.where(np.isfinite(C), C, 0.0)
