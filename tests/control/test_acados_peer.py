"""The acados benchmark's own assumptions (benchmarks/acados/peer.py; acados itself is not installed in CI).

acados 0.2.2 has no constraint masks: the peer gives every one-sided row ``h + pi >= 0`` a finite upper bound
(``peer.UPPER``) that must lie above anything the row can reach, or acados would solve another problem. Held here from
the rows' formulas: the alignment row ``(1 - v12)(1 - v10) - mu`` with ``v`` cosines in [-1, 1] reaches at most
``4 - mu``; the separation row ``2 d^2 (x - d^2) / (x + d^2)`` stays below ``2 d^2`` for every distance ``x``.
"""

import importlib.util
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from aerorelay.assembly import parse_scenario
from aerorelay.assembly.parts import ocp_spec

PEER = Path(__file__).resolve().parents[2] / "benchmarks" / "acados" / "peer.py"


def _peer():
    spec = importlib.util.spec_from_file_location("acados_peer", PEER)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_rows_upper_bound_lies_above_what_the_row_reaches():
    peer = _peer()
    spec = ocp_spec(parse_scenario({}), neighbours=2)
    upper = peer.row_upper_bounds(spec)
    assert upper.size == spec.ng
    xa, w, p = ca.SX.sym("xa", spec.nx), ca.SX.sym("w", spec.nw), spec.params.symbol()
    s = spec.stage_vars(xa, w, p)
    rows = ca.Function("h", [xa, w, p], [ca.vertcat(*[c.expression(s) for c in spec.constraints])])  # without slacks
    rng = np.random.default_rng(7)
    reached = -np.inf * np.ones(spec.ng)
    for _ in range(2000):
        x, u, P = rng.normal(size=spec.nx) * 10, rng.normal(size=spec.nw), rng.normal(size=spec.n_params) * 10
        P[spec.params["separation_m"]] = 20.0  # the largest separation the bound admits: 2 d^2 = 800 < 1000
        P[spec.params["mu"]] = 0.0  # the alignment row's largest reach, 4 - mu
        reached = np.maximum(reached, np.array(rows(x, u, P)).ravel())
    assert np.all(reached < upper), (reached, upper)
    # the formulas' suprema themselves lie below the bounds
    assert 4.0 < peer.UPPER["mutual_alignment"] and 2 * 20.0**2 < peer.UPPER["separation"]


def test_a_separation_beyond_the_bound_is_refused_before_replaying():
    peer = _peer()
    spec = ocp_spec(parse_scenario({}), neighbours=1)
    P = np.zeros((3, spec.n_params, spec.horizon + 1))
    P[:, spec.params["separation_m"], :] = 2.0
    peer.check_upper_bounds(spec, P)  # 2 d^2 = 8: within
    P[1, spec.params["separation_m"], 4] = 30.0
    with pytest.raises(SystemExit, match="separation 30 m"):
        peer.check_upper_bounds(spec, P)
