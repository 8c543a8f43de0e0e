"""acados' SQP_RTI on aerorelay's OCP, replaying the steps `aerorelay codegen --record` wrote.

Runs in the acados environment (`setup.sh`: `comma-deps-acados` with its own CasADi, aerorelay's sources without
theirs), never in aerorelay's. The OCP is rebuilt from the tree's `manifest.json` (`OcpSpec.from_description`, its
`key()` checked against the tree's) and handed to acados term for term:

- dynamics: `disc_dyn_expr` = `OcpSpec.discrete_dynamics` (one RK4 step per Ts, the state augmented with the last input);
- cost: `NONLINEAR_LS` on `stage_residual` / `terminal_residual` with `W = I / Ts` on the stages and `W_e = I` (acados
  scales a stage's cost by its time step and halves every cost: the same minimiser as aerorelay's `sum |r|^2`), the
  weights and references as stage parameters (the recording's, stage by stage);
- soft rows as aerorelay has them: each slack a control (`w = (u, pi)`), `pi >= 0`, every row `h + pi >= 0` as
  `con_h_expr`; stage 0's rows relaxed and its slacks fixed to 0 (aerorelay has no rows there); acados 0.2.2 has no
  masks, so one-sided rows get a finite upper bound above anything the row reaches (`UPPER`);
- bounds: the workspace and the rotor speeds on stages 1..N (`hpipm_rti.stage_bounds`), the rotor accelerations on
  every stage, x0 the recorded state and last input.

    python peer.py build TREE DIR --cond-n 10          # generate and compile the solver into DIR (once)
    python peer.py replay TREE DIR STEPS.csv --rounds 1 --out times.csv

`replay` writes one line per step and round: round, step, acados' own `time_tot` (ns, its C clock), the QP's
interior-point iterations, acados' status, then the first command (Hz/s).
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import sys
from pathlib import Path

import numpy as np

# a one-sided row's upper bound per constraint (acados 0.2.2 has no masks; a huge bound slows HPIPM): above anything the
# row reaches. mutual_alignment: (1 - v12)(1 - v10) - mu <= 4; separation: the bounded row 2 d^2 (...) / (...) <= 2 d^2;
# obstacles: a plane's margin (m), any distance in the workspace.
UPPER = {"mutual_alignment": 10.0, "separation": 1e3, "obstacles": 1e5}
RELAXED = -1e9  # stage 0's rows: aerorelay has none there


def _acados():
    import acados

    os.environ.setdefault("ACADOS_SOURCE_DIR", acados.DIR)
    os.environ.setdefault("TERA_PATH", acados.TERA_PATH)
    os.environ.setdefault("ACADOS_PYTHON_INTERFACE_PATH", acados.TEMPLATE_DIR)
    for lib in ("libblasfeo", "libhpipm", "libqpOASES_e", "libacados"):  # before the solver's library needs them
        ctypes.CDLL(os.path.join(acados.LIB_DIR, lib + ".so"), mode=ctypes.RTLD_GLOBAL)
    sys.path.insert(0, os.path.dirname(acados.TEMPLATE_DIR))
    import acados_template

    return acados_template


def ocp_of(tree: Path):
    """The tree's OCP (its manifest's description), checked against the tree's key."""
    from aerorelay.control.ocp import OcpSpec

    manifest = json.loads((tree / "manifest.json").read_text())
    if "ocp" not in manifest:
        raise SystemExit(f"{tree}/manifest.json has no OCP description: write the tree with this aerorelay")
    spec = OcpSpec.from_description(manifest["ocp"])
    if spec.key() != manifest["ocp_key"]:
        raise SystemExit(f"{tree}: the OCP rebuilt here differs from the tree's (key mismatch): the same aerorelay "
                         "sources must be on both sides")
    if not spec.exact_input_rate:
        raise SystemExit("peer.py: the OCP with the exact input-rate cost only (controller.exact_input_rate = true)")
    return spec, manifest


def row_upper_bounds(spec) -> np.ndarray:
    """Each constraint row's finite upper bound (``UPPER`` by its constraint)."""
    import casadi as ca

    xa, w, p = ca.SX.sym("xa", spec.nx), ca.SX.sym("w", spec.nw), spec.params.symbol()
    s = spec.stage_vars(xa, w, p)
    return np.concatenate([np.full(int(c.expression(s).shape[0]), UPPER.get(c.name, 1e5)) for c in spec.constraints]) \
        if spec.constraints else np.zeros(0)


def slack_upper_bounds(spec) -> np.ndarray:
    return np.array([UPPER.get(c.name, 1e5) for c in spec.soft_constraints])


def solver(tree: Path, folder: Path, cond_n: int, *, build: bool, settings: dict | None = None):
    """acados' SQP_RTI for the tree's OCP, generated and compiled into ``folder`` (``build``) or loaded from it."""
    at = _acados()
    import casadi as ca

    from aerorelay.control.hpipm_rti import stage_bounds
    from aerorelay.control.ocp import HESSIAN_REG

    spec, manifest = ocp_of(tree)
    N, nx, nw, ns = spec.horizon, spec.nx, spec.nw, spec.ns
    xa, w, p = ca.SX.sym("xa", nx), ca.SX.sym("w", nw), spec.params.symbol()
    model = at.AcadosModel()
    model.name = "aerorelay_peer"
    model.x, model.u, model.p = xa, w, p
    model.disc_dyn_expr = spec.discrete_dynamics(xa, w, p)
    model.cost_y_expr = spec.stage_residual(xa, w, p)
    model.cost_y_expr_e = spec.terminal_residual(xa, p)
    if spec.constraints:
        model.con_h_expr = spec.constraint_expr(xa, w, p)
    ocp = at.AcadosOcp()
    ocp.model = model
    ocp.dims.N = N
    ny, ny_e = int(model.cost_y_expr.shape[0]), int(model.cost_y_expr_e.shape[0])
    ocp.cost.cost_type, ocp.cost.cost_type_e = "NONLINEAR_LS", "NONLINEAR_LS"
    ocp.cost.W, ocp.cost.W_e = np.eye(ny) / spec.ts, np.eye(ny_e)
    ocp.cost.yref, ocp.cost.yref_e = np.zeros(ny), np.zeros(ny_e)
    ocp.parameter_values = np.zeros(spec.n_params)
    idx, lbx, ubx, lbu, ubu = stage_bounds(spec)
    ocp.constraints.x0 = np.zeros(nx)
    ocp.constraints.idxbx, ocp.constraints.lbx, ocp.constraints.ubx = idx, lbx, ubx
    ocp.constraints.idxbx_e, ocp.constraints.lbx_e, ocp.constraints.ubx_e = idx, lbx, ubx
    ocp.constraints.idxbu = np.arange(nw)
    ocp.constraints.lbu = np.r_[lbu, np.zeros(ns)]
    ocp.constraints.ubu = np.r_[ubu, slack_upper_bounds(spec)]
    if spec.constraints:
        uh = row_upper_bounds(spec)
        ocp.constraints.lh, ocp.constraints.uh = np.zeros(uh.size), uh
    o = ocp.solver_options
    o.tf = N * spec.ts
    o.integrator_type = "DISCRETE"
    o.nlp_solver_type = "SQP_RTI"
    o.hessian_approx = "GAUSS_NEWTON"
    o.qp_solver = "PARTIAL_CONDENSING_HPIPM"
    o.qp_solver_cond_N = cond_n
    o.hpipm_mode = "SPEED_ABS"
    o.qp_solver_iter_max = int((settings or {}).get("iter_max", 50))
    o.qp_solver_warm_start = 1
    o.levenberg_marquardt = HESSIAN_REG
    o.print_level = 0
    o.ext_fun_compile_flags = "-O3"
    folder.mkdir(parents=True, exist_ok=True)
    ocp.code_export_directory = str(folder / "c_generated_code")
    cwd = os.getcwd()
    os.chdir(folder)  # acados writes its build files beside the json
    try:
        s = at.AcadosOcpSolver(ocp, json_file=str(folder / "acados_ocp.json"), build=build, generate=build, verbose=False)
    finally:
        os.chdir(cwd)
    s.options_set("qp_tol_comp", float((settings or {}).get("tol_comp", 1e-3)))
    s.options_set("warm_start_first_qp", 1)
    if ns:  # stage 0: slacks fixed to 0, rows relaxed (aerorelay has none there)
        s.constraints_set(0, "ubu", np.r_[ubu, np.zeros(ns)])
    if spec.constraints:
        s.constraints_set(0, "lh", np.full(row_upper_bounds(spec).size, RELAXED))
    return s, spec


def read_steps(steps: Path, spec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The recording's shift flags, initial states ``(x, u_prev)`` and stage parameters ``(n, n_params, N + 1)``."""
    nxa, n_p, N = spec.nx, spec.n_params, spec.horizon
    shifts, x0s = [], []
    for i, line in enumerate(steps.read_text().splitlines(), 1):
        f = line.split(",")
        if f[0] == "step":
            shifts.append(float(f[1]) != 0.0), x0s.append([float(v) for v in f[2 : 2 + nxa]])
        elif f[0] == "fly":
            shifts.append(float(f[2]) != 0.0), x0s.append([float(v) for v in f[3 : 3 + nxa]])
        else:
            raise SystemExit(f"{steps}: line {i} is neither a step nor a fly event")
    P = np.loadtxt(str(steps) + ".params", delimiter=",", ndmin=2)
    if P.shape != (len(x0s), n_p * (N + 1)):
        raise SystemExit(f"{steps}.params: {P.shape}, the recording needs ({len(x0s)}, {n_p * (N + 1)})")
    return np.array(shifts), np.array(x0s), P.reshape(len(x0s), N + 1, n_p).transpose(0, 2, 1)


def check_upper_bounds(spec, P) -> None:
    """The recording's separation (``separation_m``) within what ``UPPER`` allows its row (< 2 d^2)."""
    if "separation_m" in spec.params.names:
        d = float(np.max(P[:, spec.params["separation_m"], :]))
        if 2.0 * d * d >= UPPER["separation"]:
            raise SystemExit(f"peer.py: separation {d:g} m: its row reaches 2 d^2 = {2 * d * d:g}, above acados' upper "
                             f"bound {UPPER['separation']:g} (peer.UPPER)")


def replay(s, spec, shifts, x0s, P, rounds: int, out) -> None:
    N, nr = spec.horizon, spec.n_rotors
    for r in range(rounds):
        s.reset()
        for j in range(N + 1):  # the first guess: the first state held
            s.set(j, "x", x0s[0])
        for k in range(len(x0s)):
            if shifts[k] and k > 0:  # the plan moved one stage, as aerorelay's engine shifts its own
                xs = [s.get(j, "x") for j in range(N + 1)]
                us = [s.get(j, "u") for j in range(N)]
                for j in range(N):
                    s.set(j, "x", xs[j + 1])
                    s.set(j, "u", us[min(j + 1, N - 1)])
            s.set(0, "lbx", x0s[k])
            s.set(0, "ubx", x0s[k])
            for j in range(N + 1):
                s.set(j, "p", P[k, :, j])
            status = s.solve()
            t_ns = float(np.ravel(s.get_stats("time_tot"))[0]) * 1e9
            it = int(np.sum(s.get_stats("qp_iter")))
            u = s.get(0, "u")[:nr]
            out.write(f"{r},{k},{t_ns:.0f},{it},{status}," + ",".join(repr(float(v)) for v in u) + "\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    b = sub.add_parser("build", help="generate and compile acados' solver for a tree's OCP")
    b.add_argument("tree", type=Path)
    b.add_argument("folder", type=Path)
    b.add_argument("--cond-n", type=int, default=10)
    rp = sub.add_parser("replay", help="replay a recording through a built solver")
    rp.add_argument("tree", type=Path)
    rp.add_argument("folder", type=Path)
    rp.add_argument("steps", type=Path)
    rp.add_argument("--cond-n", type=int, default=10)
    rp.add_argument("--rounds", type=int, default=1)
    rp.add_argument("--out", type=Path, required=True)
    a = ap.parse_args(argv)
    settings = json.loads((a.tree / "manifest.json").read_text()).get("engine", {})
    if a.cmd == "build":
        solver(a.tree.resolve(), a.folder.resolve(), a.cond_n, build=True, settings=settings)
        return 0
    s, spec = solver(a.tree.resolve(), a.folder.resolve(), a.cond_n, build=False, settings=settings)
    shifts, x0s, P = read_steps(a.steps, spec)
    check_upper_bounds(spec, P)
    with open(a.out, "w") as out:
        replay(s, spec, shifts, x0s, P, a.rounds, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
