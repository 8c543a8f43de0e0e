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
    (nJ,))`` -> capacity ``(M, K)``: relay positions m (world) x relay antenna axes (unit, world),
    powers W. The scene's other moving node is the source (its pose given); fixed nodes as placed."""

    def __init__(self, scene: RadioScene, n_positions: int, n_axes: int, *, source: str, relay: str | None = None):
        """``relay``: the node on the grid (default: the scene's first relay)."""
        self.m, self.k, self.nj = int(n_positions), int(n_axes), len(scene.jammers)
        relay = relay or scene.name_of("relay")
        self._call = BufferedCall(compiled(self._grid_function(scene, source, relay), "relay_grid"))
        self._z = self._call.arg

    def _grid_function(self, scene: RadioScene, source: str, relay: str) -> ca.Function:
        """``z = (vec(P) (3M), vec(B) (3K), p2, b2, vec(pJ) (3 nJ), P_J)`` -> capacities, index ``m K + k``."""
        nj, m, k = self.nj, self.m, self.k
        p, b, rest = ca.SX.sym("p", 3), ca.SX.sym("b", 3), ca.SX.sym("rest", 6 + 4 * nj)
        pj = [rest[6 + 3 * i: 9 + 3 * i] for i in range(nj)]
        state = scene.evaluate(0.0, {relay: NodePose(p, b), source: NodePose(rest[0:3], rest[3:6])},
                               jammer_positions=pj, jammer_powers=[rest[6 + 3 * nj + i] for i in range(nj)])
        one = ca.Function("relay_capacity", [p, b, rest], [state.capacity])
        z = ca.MX.sym("z", 3 * m + 3 * k + 6 + 4 * nj)
        n = m * k
        positions = ca.mtimes(ca.reshape(z[:3 * m], 3, m), ca.DM(np.kron(np.eye(m), np.ones((1, k)))))
        axes = ca.repmat(ca.reshape(z[3 * m:3 * (m + k)], 3, k), 1, m)
        grid = one.map(n, "serial")(positions, axes, ca.repmat(z[3 * (m + k):], 1, n))
        return ca.Function("relay_grid", [z], [ca.densify(grid)])

    def __call__(self, positions, axes, source_pose: NodePose, jammer_positions, jammer_powers) -> np.ndarray:
        P, B = np.asarray(positions, float), np.asarray(axes, float)
        pj = np.asarray(jammer_positions, float).reshape(-1, 3)
        PJ = np.asarray(jammer_powers, float).ravel()
        if P.shape != (self.m, 3) or B.shape != (self.k, 3) or pj.shape[0] != self.nj or PJ.shape != (self.nj,):
            raise ValueError(f"relay grid: built for {self.m} positions, {self.k} axes and {self.nj} jammer(s), got "
                             f"positions {P.shape}, axes {B.shape}, jammer positions {pj.shape}, powers {PJ.shape}")
        o = 3 * (self.m + self.k)
        self._z[:3 * self.m], self._z[3 * self.m:o] = P.ravel(), B.ravel()
        self._z[o:o + 3], self._z[o + 3:o + 6] = source_pose.position, source_pose.axis
        self._z[o + 6:o + 6 + 3 * self.nj], self._z[o + 6 + 3 * self.nj:] = pj.ravel(), PJ
        C = self._call().reshape(self.m, self.k)
        # a jammer on a receiver: the numpy evaluation's infinite interference, capacity 0
        return np.where(np.isfinite(C), C, 0.0)
