"""One relay's controller as a self-contained C99 tree (``aerorelay codegen``; issue 62).

The tree holds what the Python controller of the scenario's first relay runs each control period
(``RelayController.step``), compiled from the same sources in the same order with the same flags: the
CasADi-generated stage linearization, the HPIPM driver (``control/rti_hpipm.c``), the NMPC's own steps around it
(``control/ar_controller.c``: the lagged input-rate rows of the stage parameters, the initial state, the first input
clipped to the motor limits), and the step (``control/ar_failsafe.c``: the supervisor's envelope, the hand-over
counts, the fail-safe brake law with SciPy's BVLS allocation), with the scenario's settings baked in; one header with
a small C API; a Makefile and a CMake project that find HPIPM and BLASFEO at a prefix (default: the libraries in
CasADi's wheel this tree was written with, so it builds offline); and ``replay``, which runs recorded steps through
the library (``record_calls`` records them from a Python flight). The tree's text files (its header, Makefile, CMake
project, README, toolchain file) are templates in ``assembly/templates`` (``render``); its C sources are aerorelay's own
(``control/*.c``) and CasADi's generated code, every global name carrying the tree's prefix (``tree_names``). Where the
relay flies the paper's planner, the
tree carries it too (``control/ar_planner.c`` with the CasADi-generated expansion as its own translation unit:
``ar_plan`` makes the stage parameters). ``flown_by_c`` flies a scenario with the tree's shared library's commands
(``CController``).
"""

from __future__ import annotations

import contextlib
import ctypes
import io
import json
import os
import re
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from importlib import resources
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from ..config import Scenario
from ..control.hpipm_rti import ENGINE_FLAGS, SIMD_HEAD, _casadi_dir, engine_parts, engine_settings, simd_source, stage_bounds
from ..control.network import SEPARATION_MARGIN_M, LoopRelay, NetworkController
from ..control.nmpc import NmpcSettings, rti_options
from ..control.relay import RelayController
from ..control.relay_step import RelayStep
from ..models.mission import source_trajectory
from ..models.obstacles import Box, VerticalCylinder
from ..models.state import ROTORS, V
from ..planning.trajectory_generator import Reference, TrajectoryGenerator
from ..sim.closed_loop import known_jammers
from ..stats import stats_ms
from ..store.codegen import CASADI_VERSION, generated_c
from ..store.outputs import check_output_folder
from .parts import build
from .vehicle import thrust_along_body_z

HEADER = "aerorelay_controller.h"
SOURCE = "aerorelay_controller.c"
PLANNER_SOURCE = "aerorelay_planner.c"  # the planner's CasADi-generated expansion: its own translation unit
MODEL_SOURCE = "aerorelay_model.c"  # the vehicle model's one-period-ahead step (ar_setpoint), CasADi-generated
# BLASFEO and HPIPM as the tree's CMake fetches them (-DAR_FETCH_HPIPM=ON): the commits built and flown here on
# 2026-12-06 (the whole nominal mission with the C library linked to them: docs/guide/companion-computer.md)
BLASFEO_COMMIT = "0ab5db3259c009ea62318a5e35622fe6de7ae554"
HPIPM_COMMIT = "87ef7a6ab773427a8c416030a2b9d075a744c223"


@dataclass(frozen=True)
class Tree:
    """What ``write_tree`` wrote: the folder, its files, and the dimensions of the C API."""

    folder: Path
    files: list[str]
    nx: int  # plant state
    nr: int  # rotors (inputs: motor accelerations, Hz/s)
    n_params: int  # stage parameters per stage
    horizon: int
    nxa: int  # the OCP's initial state (the plant state, and the last input with the exact input-rate cost)
    planner: bool = False  # the paper's planner is in the tree (ar_plan)
    no_planner_because: str = ""
    simd: bool = False  # this process's engine ran blasfeo_avx2.c: build with SIMD=1 for its bits (manifest simd_here)
    relay: str = ""  # the relay whose controller it is
    prefix: str = "ar"  # every C name of the tree begins with it (ar_step: <prefix>_step)


def _c_number(v: float) -> str:
    return "INFINITY" if v == np.inf else "-INFINITY" if v == -np.inf else "NAN" if v != v else repr(float(v))


def _array(ctype: str, name: str, values) -> str:
    vals = np.atleast_1d(np.asarray(values, float if ctype == "double" else int)).ravel()
    body = ", ".join(_c_number(v) if ctype == "double" else str(int(v)) for v in vals)
    return f"static const {ctype} {name}[{max(len(vals), 1)}] = {{{body if len(vals) else '0'}}};\n"


def _defines(**values) -> str:
    return "".join(f"#define AR_{k.upper()} {_c_number(float(v)) if isinstance(v, float) else int(v)}\n"
                   for k, v in values.items())


# the tree's C names: ``--prefix`` (a lowercase letter, then lowercase letters, digits or single underscores)
PREFIX_PATTERN = re.compile(r"[a-z](?:_?[a-z0-9])*")
PREFIX_MAX = 24
# prefixes the libraries the tree links already use (HPIPM's d_/s_ and BLASFEO's, CasADi's helpers)
PREFIX_TAKEN = ("d", "s", "blasfeo", "hpipm", "casadi")
# the types every tree shares, defined once in a program that links several (AERORELAY_SHARED_TYPES_1 in the header)
SHARED_NAMES = frozenset({"ar_status", "ar_info", "AR_OK", "AR_QP_FAILED", "AR_BAD_INPUT", "AR_NOT_PREPARED", "AR_FALLBACK",
                          "AR_TRUSTED", "AR_UNTRUSTED_BAD_INPUT", "AR_UNTRUSTED_NOT_FINITE", "AR_UNTRUSTED_STAMP",
                          "AR_UNTRUSTED_AHEAD", "AR_UNTRUSTED_BACKWARDS", "AR_UNTRUSTED_POSITION_JUMP",
                          "AR_UNTRUSTED_VELOCITY_JUMP"})
NAMES_HEADER = "ar_names.h"  # the tree's renames (src/): every global name the sources spell ar_/rti_/... to the prefix's


def check_prefix(prefix: str) -> str:
    """``prefix`` when it can begin every C name of a tree; a ValueError naming ``--prefix`` and the form otherwise."""
    if not isinstance(prefix, str) or len(prefix) > PREFIX_MAX or not PREFIX_PATTERN.fullmatch(prefix) or prefix in PREFIX_TAKEN:
        raise ValueError(f"codegen --prefix: {prefix!r}: every C name of the tree begins with it: a lowercase letter, then "
                         f"lowercase letters, digits and single underscores, at most {PREFIX_MAX} characters, not ending in "
                         f"'_' and none of {', '.join(PREFIX_TAKEN)} (the linked libraries'); e.g. r1")
    return prefix


def _renamed(name: str, prefix: str) -> str:
    """``name`` (ar_x, AR_X or an internal global) with the tree's prefix: ar_x -> <prefix>_x, AR_X -> <PREFIX>_X,
    other -> <prefix>_other."""
    if name.startswith("ar_"):
        return f"{prefix}_{name[3:]}"
    if name.startswith("AR_"):
        return f"{prefix.upper()}_{name[3:]}"
    return f"{prefix}_{name}"


def tree_names(header: str, prefix: str, generated: dict[str, str], driver: str) -> tuple[dict[str, str], str]:
    """The tree's renames (``ar_step`` -> ``<prefix>_step``, ``AR_NX`` -> ``<PREFIX>_NX``, internal globals
    ``<prefix>_*``; the shared types kept: ``renamed`` applies them to a text) and ``ar_names.h``: every global name
    the tree's sources spell, mapped to the prefixed one (the header's functions, type and macros; the HPIPM driver's
    functions; every CasADi-exported symbol of each generated file, ``generated``: its stem -> its C source, whose
    helpers CasADi's ``CODEGEN_PREFIX`` names)."""
    public = {n for n in re.findall(r"\bar_\w+", header) if re.search(rf"\b{n}\s*[;(]|struct {n}\b", header)}
    public |= set(re.findall(r"^#define (AR_\w+)", header, re.M))
    public -= SHARED_NAMES
    internal = set(re.findall(r"^(?!static)[A-Za-z_][\w \*]*?\b(rti_\w+)\s*\(", driver, re.M))
    for text in generated.values():
        internal |= set(re.findall(r"^CASADI_SYMBOL_EXPORT [\w\* ]*?\b(\w+)\s*\(", text, re.M))
    mapping = {n: _renamed(n, prefix) for n in sorted(public | internal)}
    names = "".join(f"#define {a} {b}\n" for a, b in mapping.items() if a != b)
    names_h = (f"/* aerorelay codegen: this tree's names begin with {prefix!r} (--prefix); the sources spell them as aerorelay's "
               f"C sources do */\n#ifndef {prefix.upper()}_AR_NAMES_H\n#define {prefix.upper()}_AR_NAMES_H\n{names}#endif\n")
    return mapping, names_h


def renamed(text: str, mapping: dict[str, str]) -> str:
    """``text`` (the public header, the tree's README) with the tree's names (``tree_names``)."""
    return re.sub(r"\b(?:ar|AR)_\w+", lambda m: mapping.get(m.group(0), m.group(0)), text)


def _with_names(source: str, prefix: str, stem: str | None = None) -> str:
    """``source`` compiled with the tree's names (``ar_names.h`` first; ``stem``: a CasADi-generated file's, its static
    helpers named ``<prefix>_<stem>_*`` by CasADi's ``CODEGEN_PREFIX``)."""
    head = f'#include "{NAMES_HEADER}"\n'
    if stem is not None:
        head += f"#define CASADI_CODEGEN_PREFIX\n#define CODEGEN_PREFIX {prefix}_{stem}_\n"
    return head + source


TEMPLATES = "templates"  # the tree's text files (assembly/templates): {{name}} placeholders, filled by ``render``


def render(template: str, **values) -> str:
    """The template file ``template`` (``assembly/templates``) with each ``{{name}}`` replaced by ``values[name]``; a
    placeholder without a value, or a value without a placeholder, is a ValueError (a template and its caller agree)."""
    text = resources.files("aerorelay.assembly").joinpath(TEMPLATES, template).read_text()
    wanted = set(re.findall(r"\{\{(\w+)\}\}", text))
    if wanted != set(values):
        raise ValueError(f"template {template}: placeholders {sorted(wanted - set(values))} have no value, values "
                         f"{sorted(set(values) - wanted)} no placeholder")
    return re.sub(r"\{\{(\w+)\}\}", lambda m: str(values[m.group(1)]), text)


def _setpoint_function(rs: RelayStep, period: float) -> ca.Function:
    """``ar_model_setpoint(x, u, a_ext) -> (x1, acc)``: the relay's state one control period ahead under the motor
    accelerations ``u`` (the model's RK4 step) and its acceleration there with ``a_ext``, as ``RelayStep.command``
    makes an autopilot's setpoints."""
    veh = rs.vehicle
    x, u, a_ext = ca.SX.sym("x", veh.nx), ca.SX.sym("u", veh.n_rotors), ca.SX.sym("a_ext", 3)
    x1 = veh.rk4_step(x, u, period)
    return ca.Function("ar_model_setpoint", [x, u, a_ext], [x1, veh.dynamics(x1, u, a_ext)[V]])


def relay_of_tree(sc: Scenario, relay: str | None) -> str:
    """The relay whose controller a C tree is: ``relay`` (``--relay``), or the only one; a named error otherwise (a
    network's relay is never chosen silently)."""
    names = [r.name for r in sc.relay_list]
    if relay is None:
        if len(names) != 1:  # one tree per relay: which one is the user's to say
            raise ValueError(f"codegen --relay: the network has relays {', '.join(names)}; a C tree is one relay's "
                             "controller: name it with --relay NAME")
        return names[0]
    if relay not in names:
        raise ValueError(f"codegen --relay {relay!r}: the scenario's relays are {', '.join(names)}")
    return relay


def _relay_controller(sc: Scenario, settings: NmpcSettings | None, relay: str) -> tuple[LoopRelay, NetworkController]:
    """Relay ``relay`` (its controller, its stepper) and the network controller around it."""
    control = build(sc, nmpc_settings=settings).closed_loop().control
    return next(r for r in control.relays if r.name == relay), control


def _c_planner(sc: Scenario, rc: RelayController, control: NetworkController) -> tuple[TrajectoryGenerator | None, str]:
    """The paper's trajectory generator of ``sc``'s one relay when the C tree can carry it (then ``""``), else None and
    why not: the C planner is the paper's one relay and source with that planner, its OCP without obstacles' planes
    or a next node's path, a bare jammer estimate aside."""
    inner: Any = control.planner
    while not isinstance(inner, TrajectoryGenerator) and getattr(inner, "planner", None) is not None:  # a wrapper's
        inner = inner.planner
    spec = rc.spec
    lacking = [n for n in ("p_ref", "v_ref", "rho_d", "p2", "psi_ref") if n not in spec.params]
    why = ("the planner is not the paper's trajectory generator" if not isinstance(inner, TrajectoryGenerator) else
           f"the OCP's stage parameters lack {', '.join(lacking)}" if lacking else
           "a network of more than one relay or source" if len(control.relays) != 1 or len(control.sources) != 1 else
           "obstacles (their separating planes read the plan)" if spec.obstacles else
           "the OCP takes a next node's path" if spec.p0_parameter else
           "the OCP keeps apart from more than the source" if spec.neighbours > 1 else "")
    return (inner if isinstance(inner, TrajectoryGenerator) and not why else None), why


def _planner_settings(rc: RelayController, control: NetworkController, gen: TrajectoryGenerator | None) -> tuple[str, str]:
    """The C planner's baked settings and its generated expansion's C source (``""`` without a planner)."""
    if gen is None:
        return "#define AR_PLAN_SZ_IW 0\n#define AR_PLAN_SZ_W 0\n", ""
    spec = rc.spec
    fun = gen.function
    zero = np.zeros(3)
    others = np.zeros((3 * spec.neighbours, spec.horizon + 1)) if spec.neighbours else None
    template = rc.parameters(Reference(p_opt=zero, p_ref=zero, v_ref=zero, a_ref=zero), zero, zero, zero, others,
                             control.separation_m + SEPARATION_MARGIN_M)
    row = {n: (spec.params[n].start if n in spec.params else -1) for n in
           ("p_ref", "v_ref", "rho_d", "p2", "psi_ref", "p_others", "a_ext")}
    baked = "".join([
        "/* the paper's planner: the trajectory generator, its reference governor, the stage parameters' layout */\n",
        _defines(plan_nz=fun.nnz_in(0), plan_sz_arg=fun.sz_arg(),
                 plan_sz_res=fun.sz_res(), plan_sz_iw=fun.sz_iw(), plan_sz_w=fun.sz_w(),
                 eig_floor=float(gen.eig_floor), relative_floor=bool(gen.relative_floor),
                 governor_speed=float(gen.governor_speed[gen.relays[0]]),
                 max_ref_accel=float(gen.max_ref_accel), period=float(control.period),
                 **{f"row_{k}": v for k, v in row.items()}),
        _array("double", "AR_PLAN_LO", gen.lo[0]), _array("double", "AR_PLAN_HI", gen.hi[0]), _array("double", "AR_WS_NMPC_MIN", spec.workspace_min),
        _array("double", "AR_WS_NMPC_MAX", spec.workspace_max),
        _array("double", "AR_TK", spec.ts * np.arange(spec.horizon + 1)),
        _array("double", "AR_P_TEMPLATE", np.ravel(template, order="F")),
    ])
    return baked, generated_c(fun, name=PLANNER_SOURCE)



def _obstacle_rows(obstacles) -> tuple[list[int], list[float]]:
    """The envelope's obstacles as ar_failsafe.c reads them: a kind (0 box, 1 vertical cylinder) and 7 numbers each."""
    kinds, data = [], []
    for o in obstacles:
        if isinstance(o, Box):
            kinds.append(0)
            data += [*o.lo, *o.hi, o.margin]
        elif isinstance(o, VerticalCylinder):
            kinds.append(1)
            data += [*o.centre, o.radius, o.z_min, o.z_max, 0.0, o.margin]
        else:  # a new obstacle kind needs its signed distance in ar_failsafe.c
            raise ValueError(f"codegen: the supervisor's obstacle {type(o).__name__} has no C signed distance")
    return kinds, data


def _failsafe_settings(rc: RelayController) -> str:
    """The supervisor's envelope, the brake law and the hand-over counts of ``rc``, baked for ar_failsafe.c."""
    env, brake, g, veh = rc.envelope, rc.brake, rc.brake.g, rc.spec.vehicle
    kinds, data = _obstacle_rows(env.obstacles if env is not None else ())
    (kr_up, kw_up), (kr_rec, kw_rec) = brake.gains[True], brake.gains[False]
    ws_lo = env.workspace_min if env is not None else rc.spec.workspace_min
    ws_hi = env.workspace_max if env is not None else rc.spec.workspace_max
    return "".join([
        "/* the supervisor's envelope, the brake law, the hand-over counts (RelayController, SafetyEnvelope, BrakeLaw) */\n",
        _defines(supervisor=env is not None, failures_to_fallback=rc.failures_to_fallback,
                 successes_to_resume=rc.successes_to_resume, n_obst=len(kinds),
                 box_tolerance=float(env.box_tolerance_m if env else 0.0),
                 ground_z=float(env.ground_z_m if env else -np.inf),
                 cos_max_tilt=float(env._cos_max_tilt if env else -1.0),
                 max_speed=float(env.max_speed_m_s if env else np.inf),
                 max_body_rate=float(env.max_body_rate_rad_s if env else np.inf),
                 rest_speed=float(env.rest_speed_m_s if env else np.inf),
                 rest_tilt_deg=float(env.rest_tilt_deg if env else np.inf),
                 max_handovers=env.max_handovers if env else 1,
                 cos_recovery=float(brake.cos_recovery), brake_freq=float(g.freq), brake_max_freq=float(g.max_freq),
                 brake_max_accel=float(g.max_accel), brake_recovery_max_accel=float(g.recovery_max_accel),
                 brake_lag=float(g.attitude_lag_s), brake_tau=float(g.motor_time_constant),
                 brake_moment_weight=float(g.moment_weight), brake_alloc_reg=float(g.allocation_reg), mass=float(veh.mass),
                 gravity=float(veh.gravity)),
        _array("int", "AR_OBST_KIND", kinds), _array("double", "AR_OBST_DATA", data),
        _array("double", "AR_WS_MIN", ws_lo), _array("double", "AR_WS_MAX", ws_hi),
        _array("double", "AR_BRAKE_LO", brake.lo), _array("double", "AR_BRAKE_HI", brake.hi),
        _array("double", "AR_ALLOC", brake.A), _array("double", "AR_W2_MIN", brake.bounds[0]),
        _array("double", "AR_W2_MAX", brake.bounds[1]), _array("double", "AR_J", np.asarray(veh.inertia, float)),
        _array("double", "AR_KR_UPRIGHT", kr_up), _array("double", "AR_KW_UPRIGHT", kw_up),
        _array("double", "AR_KR_RECOVERY", kr_rec), _array("double", "AR_KW_RECOVERY", kw_rec),
    ])




def _mavlink_headers(folder: Path) -> None:
    """MAVLink 2's C headers for the common message set, generated by pymavlink's mavgen from the XML its wheel carries
    (offline; the dialect aerorelay's bridge speaks)."""
    import pymavlink
    from pymavlink.generator import mavgen

    xml = Path(pymavlink.__file__).parent / "dialects" / "v20" / "common.xml"
    opts = mavgen.Opts(str(folder), wire_protocol="2.0", language="C", validate=False)
    with contextlib.redirect_stdout(io.StringIO()):  # mavgen prints what it generates
        if not mavgen.mavgen(opts, [str(xml)]):
            raise RuntimeError(f"codegen --offboard: pymavlink's mavgen could not generate MAVLink's C headers from {xml}")


def world_table(sc: Scenario, control: NetworkController) -> np.ndarray:
    """What the relay knows of its source and the jammers on the mission's clock, one row per control period over
    the scenario's duration (``Scenario.duration_s``): t, the source's position, velocity and acceleration (its mission file), the jammers' positions
    (row by row) and the powers the planner plans with (``sim.closed_loop.known_jammers``, as ``aerorelay fly`` tells
    them)."""
    path = source_trajectory(sc.source_list[0].mission)
    senses = sc.controller.senses_jammer_state
    rows = []
    for t in control.period * np.arange(int(np.floor(sc.duration_s / control.period + 1e-9)) + 2):
        s = path.state(float(t))
        positions, powers = known_jammers(control.scene, float(t), senses)
        rows.append(np.concatenate([[t], s.p, s.v, s.a, np.ravel(positions), powers]))
    return np.array(rows)


def _offboard_files(sc: Scenario, control: NetworkController, prefix: str) -> dict[str, str]:
    """The offboard example's program and its world table (``world_table``) as text."""
    if sc.estimates_jammers:
        raise ValueError("codegen --offboard: jammer.localization = 'estimated' needs the receivers' readings, which the "
                         "example does not measure; it knows the jammers from the scenario (world.csv): use 'oracle'")
    table = world_table(sc, control)
    nj = (table.shape[1] - 10) // 4
    head = ["t", *(f"source_{q}_{a}" for q in "pva" for a in "xyz"),
            *(f"jammer{j}_{a}" for j in range(nj) for a in "xyz"), *(f"jammer{j}_w" for j in range(nj))]
    here = Path(__file__).resolve().parent.parent / "control"
    return {"tools/offboard.c": _with_names((here / "ar_offboard.c").read_text(), prefix),
            "world.csv": ",".join(head) + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in table) + "\n"}


def write_tree(sc: Scenario, out: Path, settings: NmpcSettings | None = None, *, planner: bool = True,
               offboard: bool = False, relay: str | None = None, prefix: str = "ar",
               control: NetworkController | None = None) -> Tree:
    """Write the C tree of relay ``relay``'s controller (None: the scenario's only relay; a network's is named:
    ``relay_of_tree``) into ``out`` (created; must be new or empty:
    FileExistsError, before any work, otherwise); ``settings``: the NMPC's solver settings (default: the scenario's);
    ``planner``: with the paper's planner where the relay flies it (``ar_plan``; False: the stage parameters always
    come from outside); ``offboard``: the controller of the vehicle an autopilot flies (``ar.controller(sc,
    autopilot=True)``: thrust along body z), with the example program that flies a MAVLink vehicle in OFFBOARD through
    the library (``tools/offboard.c``, MAVLink's C headers generated by pymavlink, ``world.csv``: what the relay knows
    of the source and the jammers on the mission's clock); ``control``: the network's controller the relay's is taken
    from (a flight's own, ``assembly.c_engine``; None: built from ``sc`` and ``settings``)."""
    out = Path(out)
    if out.is_dir() and any(out.iterdir()):  # an earlier tree too: its build/ is make's, not this program's
        raise FileExistsError(f"--out: {out} exists and is not an empty folder (the C tree is written into a new or "
                              "empty one)")
    check_output_folder(out, "codegen")  # the project's rules: not a file, no file above it, no forbidden place, writable
    name = relay_of_tree(sc, relay)  # before any work
    check_prefix(prefix)
    flown = thrust_along_body_z(sc) if offboard else sc
    part, control = _relay_controller(flown, settings, name) if control is None else (control.relay(name), control)
    rc = part.stepper.controller
    nmpc = rc.nmpc
    spec, settings = nmpc.spec, nmpc.settings
    if settings.backend != "hpipm":
        raise ValueError(f"codegen: the NMPC's backend is {settings.backend!r}; the C tree is the compiled HPIPM engine")
    gen, no_planner = _c_planner(flown, rc, control) if planner else (None, "left out (--no-c-planner)")
    if offboard and gen is None:
        raise ValueError(f"codegen --offboard: the example flies with the paper's planner in C (ar_plan); this tree has "
                         f"none: {no_planner}")
    planner_baked, planner_source = _planner_settings(rc, control, gen)
    simd_here = bool(getattr(getattr(nmpc.engine, "rti", None), "simd_compiled", False))
    veh = spec.vehicle
    rc_step = part.stepper
    stale = rc_step.stale
    model_fun = _setpoint_function(rc_step, control.period)
    out.mkdir(parents=True, exist_ok=True)
    generated, macros, driver = engine_parts(spec)
    idxbx, lbx, ubx, lbu, ubu = stage_bounds(spec)
    nr = spec.n_rotors
    uprev = spec.params["u_prev"] if not spec.exact_input_rate else np.zeros(0, int)
    nxa = spec.nx
    baked = "".join([
        "/* the scenario's settings, baked in by aerorelay codegen */\n",
        _array("double", "AR_ENGINE_SETTINGS", engine_settings(spec, **rti_options(settings))),
        _array("int", "AR_IDXBX", idxbx), _array("double", "AR_LBX", lbx), _array("double", "AR_UBX", ubx),
        _array("double", "AR_LBU", lbu), _array("double", "AR_UBU", ubu),
        _array("int", "AR_UPREV_ROWS", np.arange(uprev.start, uprev.stop) if isinstance(uprev, slice) else uprev),
        _array("double", "AR_OMEGA_MIN", np.broadcast_to(veh.omega_min, nr)),
        _array("double", "AR_OMEGA_MAX", np.broadcast_to(veh.omega_max, nr)),
        _array("double", "AR_OMEGA_DOT_MIN", np.broadcast_to(veh.omega_dot_min, nr)),
        _array("double", "AR_OMEGA_DOT_MAX", np.broadcast_to(veh.omega_dot_max, nr)),
        f"#define AR_TS {float(spec.ts)!r}\n#define AR_EXACT_INPUT_RATE {int(spec.exact_input_rate)}\n",
        f"#define AR_OMEGA_OFFSET {ROTORS.start}\n",
        _failsafe_settings(rc), planner_baked,
        _defines(model_sz_arg=model_fun.sz_arg(), model_sz_res=model_fun.sz_res(), model_sz_iw=model_fun.sz_iw(),
                 model_sz_w=model_fun.sz_w()),
    ])
    here = Path(__file__).resolve().parent.parent / "control"
    planner_api = (render("planner_api.h.in", jammers=len(gen.sp.jam_gains)) if gen is not None else
                   f"\n#define AR_HAS_PLANNER 0  /* no planner in this tree: {no_planner} */\n")
    header = render("aerorelay_controller.h.in", scenario_repr=repr(sc.name), relay_repr=repr(name), prefix_repr=repr(prefix),
                    PREFIX=prefix.upper(), nx=veh.nx, nr=nr, n_params=spec.n_params, horizon=spec.horizon, nxa=nxa,
                    control_period_s=_c_number(float(control.period)), shift=int(rc_step.shift),
                    hover_speeds=", ".join(_c_number(v) for v in rc_step.vehicle.hover_speeds()),
                    hold_after_s=_c_number(stale.hold_after_s), accel_max=_c_number(rc_step.check.a_max),
                    fallback_fraction_max=_c_number(sc.verdict.fallback_fraction_max),
                    jump_tolerance_m=_c_number(stale.jump_tolerance_m), jump_tolerance_m_s=_c_number(stale.jump_tolerance_m_s),
                    land_after_s=_c_number(stale.land_after_s), planner_api=planner_api)
    unit = "\n".join([
        "/* aerorelay codegen: the engine and the controller in one translation unit, in the order aerorelay compiles them */",
        "#include <float.h>", generated,
        "#ifdef AR_SIMD /* BLASFEO's two hottest kernels for AVX2/FMA, over CasADi's generic BLASFEO (x86-64 only) */",
        '#include "blasfeo_avx2.c"', SIMD_HEAD, "#endif", macros + driver, baked,
        (here / "ar_controller.c").read_text(), (here / "ar_failsafe.c").read_text(),
        (here / "ar_planner.c").read_text() if gen is not None else "",
    ])
    cdir = _casadi_dir()
    flags = " ".join(ENGINE_FLAGS)
    sources = {"header": HEADER, "source": SOURCE, "planner_source": PLANNER_SOURCE, "model_source": MODEL_SOURCE,
               "casadi_dir": cdir, "flags": flags}
    makefile = render("Makefile.in", **sources, offboard_make=render("offboard.mk.in") if offboard else "")
    cmake = render("CMakeLists.txt.in", **{k: v for k, v in sources.items() if k != "header"}, blasfeo_commit=BLASFEO_COMMIT,
                   hpipm_commit=HPIPM_COMMIT)
    planner_said = ("the paper's trajectory generator and its reference governor are in the tree: `ar_plan` makes the "
                    "stage parameters `P` from the source's and the jammers' states" if gen is not None else
                    f"not in this tree ({no_planner}): the stage parameters `P` come from outside")
    readme = render("README.md.in", scenario=sc.name, relay=name, casadi_version=CASADI_VERSION, planner_said=planner_said,
                    header=HEADER, prefix=prefix, nx=veh.nx, nr=nr, n_params=spec.n_params, stages=spec.horizon + 1,
                    control_period_s=_c_number(float(control.period))) + (render("README.offboard.md.in") if offboard else "")
    (out / "include").mkdir()
    (out / "src").mkdir()
    (out / "tools").mkdir()
    (out / "cmake").mkdir()
    model_source = generated_c(model_fun, name=MODEL_SOURCE)
    mapping, names_h = tree_names(header, prefix, {"gen": generated, "model": model_source, "planner": planner_source}, driver)
    files = {f"include/{HEADER}": renamed(header, mapping), f"src/{NAMES_HEADER}": names_h, f"src/{SOURCE}": _with_names(unit, prefix, "gen"),
             "src/blasfeo_avx2.c": simd_source(),
             f"src/{PLANNER_SOURCE}": _with_names(planner_source, prefix, "planner") if planner_source else
             f"/* no planner in this tree: {no_planner} */\ntypedef int ar_no_planner;\n",
             f"src/{MODEL_SOURCE}": _with_names(model_source, prefix, "model"),
             "tools/replay.c": _with_names((here / "ar_replay.c").read_text(), prefix),
             "tools/bench.c": _with_names((here / "ar_bench.c").read_text(), prefix),
             "Makefile": makefile, "CMakeLists.txt": cmake, "cmake/aarch64-linux-gnu.cmake": render("aarch64-linux-gnu.cmake"),
             "README.md": renamed(readme, mapping),
             "manifest.json": json.dumps({"scenario": sc.name, "relay": name, "casadi": CASADI_VERSION,
                                          "nx": veh.nx, "nr": nr, "n_params": spec.n_params, "horizon": spec.horizon,
                                          "nxa": nxa, "ocp_key": spec.key(), "planner": gen is not None, "prefix": prefix,
                                          "no_planner_because": no_planner,
                                          # whether the engine here ran blasfeo_avx2.c: build with SIMD=1 for its bits
                                          "simd_here": simd_here,
                                          # the OCP as data and the engine's options: a peer solver rebuilds the problem
                                          # from them (benchmarks/acados)
                                          "ocp": spec.description(), "engine": rti_options(settings)},
                                         indent=2) + "\n"}
    if offboard:
        files |= _offboard_files(flown, control, prefix)
    for path, text in files.items():
        (out / path).write_text(text)
    if offboard:
        _mavlink_headers(out / "mavlink")
    return Tree(out, sorted(files), veh.nx, nr, spec.n_params, spec.horizon, nxa, gen is not None, no_planner, simd_here,
                name, prefix)


def _fly_numbers(control: NetworkController, step: RelayStep) -> tuple[float, list[np.ndarray]]:
    """``ar_plan``'s inputs at this step: t, then the (first) source's p, v, a, the jammers' positions (row by row),
    their powers, the external acceleration the relay's stage parameters took (``NetworkController.last_plan``,
    ``RelayStep.last_a_ext``)."""
    assert control.last_plan is not None  # the network plans before its relays step
    t, sources, (pj, powers, _) = control.last_plan
    src = next(iter(sources.values()))
    return float(t), [np.asarray(src.p, float), np.asarray(src.v, float), np.asarray(src.a, float),
                      np.ravel(np.asarray(pj, float)), np.ravel(np.asarray(powers, float)), step.last_a_ext]


def recorder(relay: str, lines: list[str] | None, expected: list[np.ndarray] | None, times_ms: list[float] | None = None,
             *, fly: bool = False, params: list[np.ndarray] | None = None) -> Callable[[NetworkController], None]:
    """An installer (``experiments.run.simulate``'s ``install``) of a step backend that records every step of relay
    ``relay``'s controller as ``ar_replay.c`` reads them (``fly``: with what the planner was given, for a tree with
    the paper's planner: ``fly`` lines; else ``step`` lines with the stage parameters), its commands (the brake law's
    flag first) and ``params``: its stage parameters; ``times_ms``: each step's time (``RelayController.step``, ms)."""

    def fmt(*arrays) -> str:
        return ",".join(repr(float(v)) for a in arrays for v in np.ravel(np.asarray(a, float), order="F"))

    def install(control: NetworkController) -> None:
        def backend(step: RelayStep, x, u_prev, P, shift):
            t0 = time.perf_counter()
            info = step.controller.step(x, u_prev, P, shift)
            if times_ms is not None:
                times_ms.append((time.perf_counter() - t0) * 1e3)
            if lines is not None and expected is not None:
                if fly:
                    t, rest = _fly_numbers(control, step)
                    lines.append(f"fly,{t!r},{int(bool(shift))}," + fmt(x, u_prev, *rest))
                else:
                    lines.append(f"step,{int(bool(shift))}," + fmt(x, u_prev, P))
                expected.append(np.r_[float(info.fallback), np.asarray(info.u, float)])
                if params is not None:
                    params.append(np.ravel(np.asarray(P, float), order="F").copy())
            return info

        control.relay(relay).stepper.backend = backend

    return install


def is_recording(path: Path) -> bool:
    """Whether ``path`` is a file ``record_calls`` wrote: a recording (its first line a ``step`` or ``fly`` event) or one
    of its sidecars (``.expected``, ``.params``: rows of numbers). Read from its first line only."""
    with open(path, "rb") as f:
        first = f.readline(1 << 20).decode("ascii").strip()
    fields = first.split(",")
    if str(path).endswith((".expected", ".params")):
        return bool(first) and all(_number(v) for v in fields)
    return fields[0] in ("step", "fly") and all(_number(v) for v in fields[1:])


def _number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def record_calls(sc: Scenario, out_csv: Path, *, simulate, relay: str, fly: bool = False) -> np.ndarray:
    """Fly ``sc`` (``simulate(sc, install)``, ``install`` the recorder's installer) recording relay ``relay``'s
    controller steps into ``out_csv`` (``ar_replay.c``'s
    lines: ``fly`` lines with what the planner was given when ``fly``, for a tree with the paper's planner, else
    ``step`` lines), what they returned into ``out_csv.expected`` (one row per step: the brake law's flag, the
    command; %.17g) and their stage parameters into ``out_csv.params`` (column-major, one row per step); returns the
    ``expected`` rows."""
    lines: list[str] = []
    expected: list[np.ndarray] = []
    params: list[np.ndarray] = []
    simulate(sc, recorder(relay, lines, expected, fly=fly, params=params))
    out_csv = Path(out_csv)
    out_csv.write_text("\n".join(lines) + "\n")
    u = np.array(expected)
    np.savetxt(str(out_csv) + ".expected", u, fmt="%.17g", delimiter=",")
    np.savetxt(str(out_csv) + ".params", np.array(params), fmt="%.17g", delimiter=",")
    return u


class _Info(ctypes.Structure):
    _fields_ = [("ok", ctypes.c_int), ("qp_status", ctypes.c_int), ("iterations", ctypes.c_int),
                ("capped", ctypes.c_int), ("slack_max", ctypes.c_double), ("fallback", ctypes.c_int)]


STATUS = {0: "AR_OK", 1: "AR_QP_FAILED", 2: "AR_BAD_INPUT", 3: "AR_NOT_PREPARED", 4: "AR_FALLBACK"}


def make(tree: Tree, target: str) -> Path:
    """``make TARGET`` in a written tree with the BLASFEO kernels this process's engine ran (``Tree.simd``); the
    target's path. No make, or a failed build: a RuntimeError with make's last output."""
    if shutil.which("make") is None:
        raise RuntimeError("codegen: make (and a C compiler) is needed to build the C tree")
    res = subprocess.run(["make", "-C", str(tree.folder), f"SIMD={int(tree.simd)}", target], capture_output=True,
                         text=True)
    if res.returncode != 0:
        raise RuntimeError(f"codegen: make {target} failed in {tree.folder}:\n{(res.stdout + res.stderr)[-2000:]}")
    return tree.folder / target


def build_shared(tree: Tree) -> Path:
    """The tree's shared library (``make shared``)."""
    make(tree, "shared")
    return tree.folder / "build" / "libaerorelay_controller.so"


class CController:
    """One controller of a tree's shared library (``build_shared``) through ctypes: ``step`` is ``<prefix>_step``."""

    def __init__(self, library: Path, tree: Tree):
        lib = ctypes.CDLL(str(library))
        self.create, self.destroy, self.c_step = (getattr(lib, f"{tree.prefix}_{n}") for n in ("create", "destroy", "step"))
        self.create.restype = ctypes.c_void_p
        self.destroy.argtypes = [ctypes.c_void_p]
        dbl = ctypes.POINTER(ctypes.c_double)
        self.c_step.argtypes = [ctypes.c_void_p, dbl, dbl, dbl, ctypes.c_int, dbl, ctypes.POINTER(_Info)]
        self.c_step.restype = ctypes.c_int
        self.c_guess, self.c_failsafe = getattr(lib, f"{tree.prefix}_guess"), getattr(lib, f"{tree.prefix}_failsafe_state")
        self.c_guess.argtypes = [ctypes.c_void_p, dbl]
        self.c_failsafe.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_int)]
        self.c_guess.restype = self.c_failsafe.restype = ctypes.c_int
        if tree.planner:
            self.c_plan = getattr(lib, f"{tree.prefix}_plan")
            self.c_plan.argtypes = [ctypes.c_void_p, ctypes.c_double, *[dbl] * 8]
            self.c_plan.restype = ctypes.c_int
        self.lib, self.tree = lib, tree
        self.handle = self.create()
        if not self.handle:
            raise MemoryError(f"codegen: {tree.prefix}_create returned NULL")
        self.u = np.zeros(tree.nr)

    def step(self, x, u_prev, P, shift: bool) -> tuple[str, _Info, np.ndarray]:
        """The C step for the state ``x``, the last input, the stage parameters ``P`` ``(n_params, N + 1)``."""
        t = self.tree
        x = np.ascontiguousarray(x, float).reshape(t.nx)
        up = np.ascontiguousarray(u_prev, float).reshape(t.nr)
        Pf = np.asfortranarray(np.asarray(P, float).reshape(t.n_params, t.horizon + 1)).ravel(order="F")
        info = _Info()
        ptr = ctypes.POINTER(ctypes.c_double)
        status = self.c_step(self.handle, x.ctypes.data_as(ptr), up.ctypes.data_as(ptr), Pf.ctypes.data_as(ptr),
                                  int(bool(shift)), self.u.ctypes.data_as(ptr), ctypes.byref(info))
        return STATUS.get(status, str(status)), info, self.u.copy()

    def plan(self, t: float, x, numbers: list[np.ndarray]) -> tuple[str, np.ndarray]:
        """``ar_plan``: the stage parameters ``(n_params, N + 1)`` the C planner makes at ``t`` for the state ``x`` from
        ``numbers`` (the source's p, v, a, the jammers' positions and powers, the external acceleration)."""
        tr = self.tree
        ptr = ctypes.POINTER(ctypes.c_double)
        args = [np.ascontiguousarray(a, float) for a in (x, *numbers)]
        P = np.zeros(tr.n_params * (tr.horizon + 1))
        status = self.c_plan(self.handle, float(t), *[a.ctypes.data_as(ptr) for a in args], P.ctypes.data_as(ptr))
        return STATUS.get(status, str(status)), P.reshape(tr.n_params, tr.horizon + 1, order="F")

    def guess(self) -> np.ndarray | None:
        """``<prefix>_guess``: the plan the next step starts from, ``(nxa, N + 1)`` (the NMPC's ``plan()[0]``); None
        before the first step."""
        t = self.tree
        X = np.zeros(t.nxa * (t.horizon + 1))
        status = self.c_guess(self.handle, X.ctypes.data_as(ctypes.POINTER(ctypes.c_double)))
        return X.reshape(t.nxa, t.horizon + 1, order="F") if status == 0 else None

    def failsafe_state(self) -> tuple[bool, int, int, bool]:
        """``<prefix>_failsafe_state``: whether the brake law flies now, its episodes, the envelope's hand-overs, and
        whether the last state was outside the envelope (``RelayController``'s counters)."""
        state = (ctypes.c_int * 4)()
        self.c_failsafe(self.handle, state)
        return bool(state[0]), int(state[1]), int(state[2]), bool(state[3])

    def close(self) -> None:
        if self.handle:
            self.destroy(self.handle)
            self.handle = None


@dataclass
class Shadow:
    """What flying with the C commands found: steps, the brake law's steps, the largest difference from the Python
    controller's command on the same inputs (relative to max(|u|, 1 Hz/s)), and the steps where the two disagreed on
    the brake law; with the C planner, the largest difference of its stage parameters from Python's (relative to
    max(|P|, 1))."""

    steps: int = 0
    fallback_steps: int = 0
    max_difference: float = 0.0
    fallback_disagreements: int = 0
    planned: bool = False
    max_parameter_difference: float = 0.0


def flown_by_c(controller: CController, shadow: Shadow) -> Callable[[NetworkController], None]:
    """An installer (``experiments.run.simulate``'s ``install``) of a step backend by which the tree's relay
    (``Tree.relay``) flies the C library's commands: the Python controller steps beside it on the same inputs (its plan
    feeds the stage parameters that read one: obstacle planes, a fleet's predictions) and each step's difference is
    kept in ``shadow`` (a backend installed before, the recorder, steps Python's controller). With the paper's planner in
    the tree, the C planner makes the C step's stage parameters (``ar_plan``, from what the Python planner was
    given)."""

    def install(control: NetworkController) -> None:
        inner = control.relay(controller.tree.relay).stepper.backend  # a backend installed before (the recorder) or None

        def backend(step: RelayStep, x, u_prev, P, shift):
            info = step.controller.step(x, u_prev, P, shift) if inner is None else inner(step, x, u_prev, P, shift)
            if controller.tree.planner:
                t, numbers = _fly_numbers(control, step)
                _, P_c = controller.plan(t, x, numbers)
                shadow.max_parameter_difference = max(shadow.max_parameter_difference,
                                                      float(np.max(np.abs(P_c - P) / np.maximum(np.abs(P), 1.0))))
                P = P_c
            status, cinfo, u = controller.step(x, u_prev, P, shift)
            shadow.steps += 1
            shadow.fallback_steps += bool(cinfo.fallback)
            shadow.fallback_disagreements += bool(cinfo.fallback) != bool(info.fallback)
            diff = np.abs(u - info.u) / np.maximum(np.abs(info.u), 1.0)
            shadow.max_difference = max(shadow.max_difference, float(np.max(diff)))
            return replace(info, u=u, ok=bool(cinfo.ok), fallback=bool(cinfo.fallback))

        control.relay(controller.tree.relay).stepper.backend = backend

    return install


def _pinned_core() -> set[int] | None:
    """The last core this process may run on (the benchmark pins itself and the C program there), or None."""
    try:
        cores = os.sched_getaffinity(0)
    except (AttributeError, OSError):
        return None
    return {max(cores)} if cores else None


def bench_c(sc: Scenario, settings: NmpcSettings | None = None, *, rounds: int = 3,
            say: Callable[[str], None] = lambda s: None) -> dict:
    """Time the first relay's controller step in Python and as the C tree (``tools/bench.c``, no Python in the loop) on
    the same mission, alternating, ``rounds`` times, pinned to one core: per round Python's ``RelayController.step``
    (ms) and its NMPC's preparation and feedback phases (as ``aerorelay bench`` times them), the C library's ``ar_step`` and its
    preparation and feedback phases (ms), and the steps the brake law flew (the recorded steps of the first Python
    flight are the C program's input; the C commands equal Python's, tests/control/test_codegen.py)."""
    if rounds < 1:
        raise ValueError(f"rounds must be >= 1, got {rounds}")
    pin, before = _pinned_core(), None
    out: dict = {"rounds": [], "pinned_core": sorted(pin)[0] if pin else None}
    with tempfile.TemporaryDirectory(prefix="aerorelay-bench-c-") as tmp_name:
        tmp = Path(tmp_name)
        tree = write_tree(sc, tmp / "tree", settings)
        say(f"building the C tree (make SIMD={int(tree.simd)})")
        bench = make(tree, "build/bench")
        warm = sc.with_updates({"sim.duration_s": 0.1})
        build(warm, nmpc_settings=settings).closed_loop().run()  # the Python engine compiled or loaded first
        steps = tmp / "steps.csv"
        if pin:
            before = os.sched_getaffinity(0)
            os.sched_setaffinity(0, pin)
        try:
            for r in range(rounds):
                lines: list[str] = []
                expected: list[np.ndarray] = []
                py_ms: list[float] = []
                say(f"round {r + 1}/{rounds}: Python")
                loop = build(sc, nmpc_settings=settings).closed_loop()
                recorder(tree.relay, lines if r == 0 else None, expected if r == 0 else None, py_ms)(loop.control)
                loop.run()
                timings = loop.timings[loop.relays[0].name]
                if r == 0:
                    steps.write_text("\n".join(lines) + "\n")
                    out["steps"] = len(lines)
                    out["fallback_steps"] = int(sum(e[0] for e in expected))
                say(f"round {r + 1}/{rounds}: C")
                run = subprocess.run([str(bench), str(steps), "1"], capture_output=True, text=True)
                if run.returncode != 0:
                    raise RuntimeError(f"bench --backend c: the C bench failed: {run.stderr[-1000:]}")
                ns = np.array([[float(v) for v in line.split(",")[2:]] for line in run.stdout.splitlines()])
                out["rounds"].append({
                    "python_step_ms": stats_ms(py_ms),
                    "python_preparation_ms": stats_ms([t.prep_ms for t in timings]),
                    "python_feedback_ms": stats_ms([t.feedback_ms for t in timings]),
                    "c_step_ms": stats_ms(ns[:, 0] * 1e-6),
                    "c_preparation_ms": stats_ms(ns[:, 1] * 1e-6),
                    "c_feedback_ms": stats_ms(ns[:, 2] * 1e-6),
                })
        finally:
            if before is not None:
                os.sched_setaffinity(0, before)
    out["simd"] = tree.simd
    return out
