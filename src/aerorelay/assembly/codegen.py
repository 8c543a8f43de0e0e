"""One relay's NMPC as a self-contained C99 tree (``aerorelay codegen``; issue 62, its first part).

The tree holds what the Python NMPC of the scenario's first relay runs each control period, compiled from the same
sources in the same order with the same flags: the CasADi-generated stage linearization, the HPIPM driver
(``control/rti_hpipm.c``), and the NMPC's own steps around it (``control/ar_controller.c``: the lagged input-rate
rows of the stage parameters, the initial state, the first input clipped to the motor limits), with the scenario's
settings baked in; one header with a small C API; a Makefile and a CMake project that find HPIPM and BLASFEO at a
prefix (default: the libraries in CasADi's wheel this tree was written with, so it builds offline); and ``replay``,
which runs recorded calls through the library (``record_calls`` records them from a Python flight). Not in the tree
yet: the stage parameters' producers (the planner, the reference governor), the supervisor and the fail-safe:
the C library takes the stage parameters as input.
"""

from __future__ import annotations

import contextlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config import Scenario
from ..control.hpipm_rti import ENGINE_FLAGS, SIMD_HEAD, _casadi_dir, engine_parts, engine_settings, simd_source, stage_bounds
from ..control.nmpc import NMPC, rti_options
from ..models.state import ROTORS
from ..store.codegen import CASADI_VERSION
from .parts import build

HEADER = "aerorelay_controller.h"
SOURCE = "aerorelay_controller.c"


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


def _array(ctype: str, name: str, values) -> str:
    vals = np.atleast_1d(np.asarray(values, float if ctype == "double" else int)).ravel()
    body = ", ".join(repr(float(v)) if ctype == "double" else str(int(v)) for v in vals)
    return f"static const {ctype} {name}[{max(len(vals), 1)}] = {{{body if len(vals) else '0'}}};\n"


def _first_nmpc(sc: Scenario) -> NMPC:
    return build(sc).relays[0].stepper.controller.nmpc


def write_tree(sc: Scenario, out: Path) -> Tree:
    """Write the C tree of ``sc``'s first relay's NMPC into ``out`` (created; must be new or empty: FileExistsError,
    before any work, otherwise)."""
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise FileExistsError(f"--out: {out} exists and is not an empty folder (the C tree is written into a new or "
                              "empty one)")
    nmpc = _first_nmpc(sc)
    spec, settings = nmpc.spec, nmpc.settings
    if settings.backend != "hpipm":
        raise ValueError(f"codegen: the NMPC's backend is {settings.backend!r}; the C tree is the compiled HPIPM engine")
    veh = spec.vehicle
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
    ])
    here = Path(__file__).resolve().parent.parent / "control"
    header = f"""/* aerorelay: one relay's NMPC as a C library (scenario {sc.name!r}, written by aerorelay codegen).
 * See README.md. Units: SI; angles rad; rotor speeds Hz; inputs: motor accelerations, Hz/s. */
#ifndef AERORELAY_CONTROLLER_H
#define AERORELAY_CONTROLLER_H

#define AR_NX {veh.nx}  /* plant state: position (3), Euler angles ZYX (3), velocity (3), body rates (3), rotor speeds */
#define AR_NR {nr}  /* rotors: the command's length */
#define AR_NP {spec.n_params}  /* stage parameters per stage (P is AR_NP x (AR_N + 1), column-major) */
#define AR_N {spec.horizon}  /* horizon (stages) */
#define AR_NXA {nxa}  /* the OCP's initial state (ar_reset) */

typedef enum {{ AR_OK = 0, AR_QP_FAILED = 1, AR_BAD_INPUT = 2, AR_NOT_PREPARED = 3 }} ar_status;

typedef struct {{
  int ok;          /* the QP solved and its input is finite */
  int qp_status;   /* HPIPM's status (0 success, 1 max iterations, 2 min step, 3 NaN, 4 inconsistent), -2: not run */
  int iterations;  /* IPM iterations */
  int capped;      /* stopped at the iteration cap with residuals within accept_tol */
  double slack_max; /* largest slack of the solution (NaN when not ok) */
}} ar_info;

typedef struct ar_controller ar_controller;

ar_controller *ar_create(void);  /* NULL when memory cannot be had; no allocation afterwards */
void ar_destroy(ar_controller *c);
/* the plan: xa0 held over the horizon, zero inputs (done by the first ar_prepare from its x_guess) */
ar_status ar_reset(ar_controller *c, const double *xa0);
/* preparation, before the measurement: P the stage parameters, u_prev the last input, x_guess (the first call) */
ar_status ar_prepare(ar_controller *c, const double *P, const double *u_prev, const double *x_guess);
/* feedback: the measured state in, the motor accelerations u out (AR_NR); bad input: AR_BAD_INPUT, u = 0 (hold) */
ar_status ar_feedback(ar_controller *c, const double *x, const double *u_prev, int shift, double *u, ar_info *info);

#endif
"""
    unit = "\n".join([
        "/* aerorelay codegen: the engine and the controller in one translation unit, in the order aerorelay compiles them */",
        "#include <float.h>", generated,
        "#ifdef AR_SIMD /* BLASFEO's two hottest kernels for AVX2/FMA, over CasADi's generic BLASFEO (x86-64 only) */",
        '#include "blasfeo_avx2.c"', SIMD_HEAD, "#endif", macros + driver, baked,
        (here / "ar_controller.c").read_text(),
    ])
    cdir = _casadi_dir()
    flags = " ".join(ENGINE_FLAGS)
    makefile = f"""# aerorelay codegen: build the controller library and replay (make; make SIMD=1 on AVX2/FMA x86-64 with a generic
# BLASFEO; HPIPM_PREFIX / BLASFEO_PREFIX: an acados install, or CasADi's wheel, the default)
CC ?= cc
CFLAGS ?= {flags}
HPIPM_PREFIX ?= {cdir}
BLASFEO_PREFIX ?= $(HPIPM_PREFIX)
SIMD ?= 0
DEFS := $(if $(filter 1,$(SIMD)),-DAR_SIMD,)
INC := -Iinclude -Isrc -I$(HPIPM_PREFIX)/include -I$(HPIPM_PREFIX)/include/hpipm/include -I$(BLASFEO_PREFIX)/include \\
       -I$(BLASFEO_PREFIX)/include/blasfeo/include
LIBS := -L$(HPIPM_PREFIX) -L$(HPIPM_PREFIX)/lib -L$(BLASFEO_PREFIX) -L$(BLASFEO_PREFIX)/lib -lhpipm -lblasfeo -lm
RPATH := -Wl,-rpath,$(HPIPM_PREFIX) -Wl,-rpath,$(HPIPM_PREFIX)/lib -Wl,-rpath,$(BLASFEO_PREFIX) -Wl,-rpath,$(BLASFEO_PREFIX)/lib

all: build/libaerorelay_controller.a build/replay

build/aerorelay_controller.o: src/{SOURCE} src/blasfeo_avx2.c include/{HEADER}
\tmkdir -p build
\t$(CC) $(CFLAGS) $(DEFS) $(INC) -c src/{SOURCE} -o $@

build/libaerorelay_controller.a: build/aerorelay_controller.o
\tar rcs $@ $^

build/replay: tools/replay.c build/libaerorelay_controller.a
\t$(CC) $(CFLAGS) $(INC) tools/replay.c build/libaerorelay_controller.a $(LIBS) $(RPATH) -o $@

clean:
\trm -rf build

.PHONY: all clean
"""
    cmake = f"""cmake_minimum_required(VERSION 3.13)
project(aerorelay_controller C)
# aerorelay codegen: HPIPM and BLASFEO at a prefix (an acados install, or CasADi's wheel, the default)
set(HPIPM_PREFIX "{cdir}" CACHE PATH "HPIPM's install prefix")
set(BLASFEO_PREFIX "${{HPIPM_PREFIX}}" CACHE PATH "BLASFEO's install prefix")
option(AR_SIMD "BLASFEO's two hottest kernels for AVX2/FMA (x86-64, CasADi's generic BLASFEO)" OFF)
find_library(HPIPM_LIB hpipm PATHS ${{HPIPM_PREFIX}} ${{HPIPM_PREFIX}}/lib NO_DEFAULT_PATH REQUIRED)
find_library(BLASFEO_LIB blasfeo PATHS ${{BLASFEO_PREFIX}} ${{BLASFEO_PREFIX}}/lib NO_DEFAULT_PATH REQUIRED)
add_library(aerorelay_controller STATIC src/{SOURCE})
target_compile_options(aerorelay_controller PRIVATE {flags})
target_include_directories(aerorelay_controller PUBLIC include PRIVATE src ${{HPIPM_PREFIX}}/include
    ${{HPIPM_PREFIX}}/include/hpipm/include ${{BLASFEO_PREFIX}}/include ${{BLASFEO_PREFIX}}/include/blasfeo/include)
if(AR_SIMD)
  target_compile_definitions(aerorelay_controller PRIVATE AR_SIMD)
endif()
target_link_libraries(aerorelay_controller PUBLIC ${{HPIPM_LIB}} ${{BLASFEO_LIB}} m)
add_executable(replay tools/replay.c)
target_compile_options(replay PRIVATE {flags})
target_link_libraries(replay PRIVATE aerorelay_controller)
"""
    readme = f"""# aerorelay controller: scenario `{sc.name}`, relay `{sc.relay_list[0].name}`

Written by `aerorelay codegen` (aerorelay, CasADi {CASADI_VERSION}). One relay's NMPC (real-time iteration, HPIPM) as a
C99 library with the scenario's settings baked in: the command it returns equals the Python NMPC's for the same
calls (`replay`, below). The stage parameters `P` (the planner's references, the source's and the jammers' paths as
the relay knows them) come from outside: the planner, the reference governor, the supervisor and the fail-safe
are not in this tree yet.

Build (HPIPM and BLASFEO from CasADi's wheel by default, or `HPIPM_PREFIX=/opt/acados`):

    make                       # build/libaerorelay_controller.a and build/replay
    cmake -B build-cmake && cmake --build build-cmake

API: `include/{HEADER}`. Each control period: `ar_prepare(c, P, u_prev, x)` before the measurement, then
`ar_feedback(c, x, u_prev, 1, u, &info)`. Dimensions: state {veh.nx}, rotors {nr}, stage parameters {spec.n_params} x
{spec.horizon + 1}.

Check it against Python: `aerorelay codegen SCENARIO --out DIR --record calls.csv` writes the calls of a simulated
flight and the Python NMPC's commands (`calls.csv.expected`); `build/replay calls.csv` prints status, ok, HPIPM
status, iterations and the command per feedback.
"""
    (out / "include").mkdir()
    (out / "src").mkdir()
    (out / "tools").mkdir()
    files = {f"include/{HEADER}": header, f"src/{SOURCE}": unit, "src/blasfeo_avx2.c": simd_source(),
             "tools/replay.c": (here / "ar_replay.c").read_text(), "Makefile": makefile, "CMakeLists.txt": cmake,
             "README.md": readme,
             "manifest.json": json.dumps({"scenario": sc.name, "relay": sc.relay_list[0].name, "casadi": CASADI_VERSION,
                                          "nx": veh.nx, "nr": nr, "n_params": spec.n_params, "horizon": spec.horizon,
                                          "nxa": nxa, "ocp_key": spec.key(),
                                          # whether the engine here ran blasfeo_avx2.c: build with SIMD=1 for its bits
                                          "simd_here": bool(getattr(getattr(nmpc.engine, "rti", None), "simd_compiled", False))},
                                         indent=2) + "\n"}
    for name, text in files.items():
        (out / name).write_text(text)
    return Tree(out, sorted(files), veh.nx, nr, spec.n_params, spec.horizon, nxa)


@contextlib.contextmanager
def _recording(lines: list[str], expected: list[np.ndarray]):
    """Every call of the first NMPC that runs, as ``ar_replay.c`` reads them, and its commands."""
    first: list[int] = []
    reset, prepare, feedback = NMPC.reset, NMPC.prepare, NMPC.feedback

    def mine(self) -> bool:
        if not first:
            first.append(id(self))
        return first[0] == id(self)

    def fmt(*arrays) -> str:
        return ",".join(repr(float(v)) for a in arrays for v in np.ravel(np.asarray(a, float), order="F"))

    def rec_reset(self, xa0):
        if mine(self):
            lines.append("reset," + fmt(xa0))
        return reset(self, xa0)

    def rec_prepare(self, P, u_prev, x_guess=None):
        out = prepare(self, P, u_prev, x_guess)  # a first call's reset is recorded (by rec_reset) before it
        if mine(self):
            lines.append("prepare," + fmt(x_guess if x_guess is not None else np.zeros(self.spec.vehicle.nx), u_prev, P))
        return out

    def rec_feedback(self, x, u_prev, shift=True):
        info = feedback(self, x, u_prev, shift)
        if mine(self):
            lines.append(f"feedback,{int(bool(shift))}," + fmt(x, u_prev))
            expected.append(np.asarray(info.u, float).copy())
        return info

    patched = {"reset": rec_reset, "prepare": rec_prepare, "feedback": rec_feedback}
    for name, fn in patched.items():
        setattr(NMPC, name, fn)
    try:
        yield
    finally:
        for name, fn in {"reset": reset, "prepare": prepare, "feedback": feedback}.items():
            setattr(NMPC, name, fn)


def record_calls(sc: Scenario, out_csv: Path, *, simulate) -> np.ndarray:
    """Fly ``sc`` (``simulate(sc)``) recording its first relay's NMPC calls into ``out_csv`` (``ar_replay.c``'s
    events) and its commands into ``out_csv.expected`` (one row per feedback, %.17g); returns the commands."""
    lines: list[str] = []
    expected: list[np.ndarray] = []
    with _recording(lines, expected):
        simulate(sc)
    out_csv = Path(out_csv)
    out_csv.write_text("\n".join(lines) + "\n")
    u = np.array(expected)
    np.savetxt(str(out_csv) + ".expected", u, fmt="%.17g", delimiter=",")
    return u
