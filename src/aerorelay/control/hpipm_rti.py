"""The RTI as two compiled calls: CasADi-generated stage linearization + HPIPM.

``rti_hpipm.c`` is appended to the C code CasADi generates for the per-stage linearization of
``ocp.py`` and linked against the HPIPM and BLASFEO libraries that ship in CasADi's wheel (no
extra dependency). Every dimension is taken from the OCP description and checked against the
generated functions before compiling (``linearization.check_dimensions``). Compared with
``casadi.conic('hpipm')`` this keeps HPIPM's structures alive between steps, drops the variables
the conic route fixes by equal bounds (initial state, stage-0 slacks), can partially condense
the horizon, and splits each step into ``prepare(P)`` (before the measurement) and
``feedback(xa0)`` (measurement in, input out), like acados' RTI phases.
"""

from __future__ import annotations

import ctypes
import hashlib
import json
import logging
import os
import platform
import subprocess
import sys
from functools import cache
from importlib import resources
from pathlib import Path

import casadi as ca
import numpy as np

from ..store.codegen import CASADI_VERSION, cache_dir, generated_c, shared_library
from .blasfeo_contract import KERNEL_CONTRACTS, contract_violations
from .linearization import check_dimensions, stage_linearization, terminal_linearization
from .ocp import INF, OcpSpec, absolute_bounds

log = logging.getLogger(__name__)
_dp = ctypes.POINTER(ctypes.c_double)


class RtiInfo(ctypes.Structure):
    """Mirror of ``rti_info`` in rti_hpipm.c: the feedback phase's outcome."""

    _fields_ = [("ok", ctypes.c_int), ("status", ctypes.c_int), ("iter", ctypes.c_int), ("capped", ctypes.c_int),
                ("slack_max", ctypes.c_double), ("res_max", ctypes.c_double)]


def _casadi_dir() -> Path:
    return Path(ca.__file__).parent


def cpu_has_avx2_fma() -> bool:
    """Whether this (Linux, x86-64) CPU advertises AVX2 and FMA (False where it cannot be told)."""
    try:
        flags = Path("/proc/cpuinfo").read_text().split()
    except OSError:
        return False
    return platform.machine() in ("x86_64", "AMD64") and "avx2" in flags and "fma" in flags


@cache
def blasfeo_matches_avx2_kernels() -> tuple[bool, str]:
    """Run-time check that the BLASFEO in CasADi's wheel is what ``blasfeo_avx2.c`` was written
    for (see ``check_blasfeo_in_this_process``). Run in a child process, since loading
    libblasfeo here before the engine would bind its kernel calls to the generic kernels for
    good; the verdict is cached on disk per libblasfeo file. Returns ``(ok, reason)``."""
    lib = _casadi_dir() / "libblasfeo.so"
    try:
        st = lib.stat()
    except OSError as err:
        return False, f"no libblasfeo ({err})"
    checked = ",".join(sorted(KERNEL_CONTRACTS))  # a verdict on fewer kernels does not cover more
    tag = hashlib.sha256(f"{lib.resolve()}|{st.st_size}|{st.st_mtime_ns}|{CASADI_VERSION}|{checked}".encode()).hexdigest()[:16]
    verdict = cache_dir() / f"blasfeo_check_{tag}.json"
    if verdict.exists():
        try:
            ok, reason = json.loads(verdict.read_text())
            return bool(ok), str(reason)
        except (OSError, ValueError, TypeError):
            log.warning("kernel check %s is corrupt: checked again", verdict)
    code = "import json; from aerorelay.control.hpipm_rti import check_blasfeo_in_this_process as c; print(json.dumps(c()))"
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if res.returncode != 0:
        return False, f"BLASFEO check failed to run: {res.stderr.strip()[-300:]}"
    ok, reason = json.loads(res.stdout.strip().splitlines()[-1])
    try:
        verdict.parent.mkdir(parents=True, exist_ok=True)
        tmp = verdict.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps([ok, reason]))
        os.replace(tmp, verdict)
    except OSError as err:  # an unwritable cache only costs the check next time
        log.warning("kernel check not cached (%s)", err)
    return bool(ok), str(reason)


def check_blasfeo_in_this_process() -> tuple[bool, str]:
    """The generic target (its headers), panel size 4, and every kernel ``blasfeo_avx2.c``
    replaces computing its contract (``blasfeo_contract.KERNEL_CONTRACTS``). Loads libblasfeo
    into this process."""
    cdir = _casadi_dir()
    target = cdir / "include" / "blasfeo_target.h"
    try:
        if "#define TARGET_GENERIC" not in target.read_text():
            return False, "CasADi's BLASFEO is not the generic build"
        lib = ctypes.CDLL(str(cdir / "libblasfeo.so"))
        memsize = lib.blasfeo_memsize_dmat
        memsize.restype, memsize.argtypes = ctypes.c_size_t, [ctypes.c_int, ctypes.c_int]
        if memsize(4, 4) != memsize(1, 4) or memsize(5, 4) <= memsize(4, 4):  # rows 1-4 share a panel, row 5 starts one
            return False, "BLASFEO's panel size is not 4"
        bad = contract_violations(lib)
    except (OSError, AttributeError) as err:
        return False, f"BLASFEO not usable for the check ({err})"
    if bad:
        return False, f"BLASFEO's kernels have another contract: {', '.join(bad)}"
    return True, "generic BLASFEO, panel size 4"


class _DlInfo(ctypes.Structure):
    _fields_ = [("dli_fname", ctypes.c_char_p), ("dli_fbase", ctypes.c_void_p), ("dli_sname", ctypes.c_char_p),
                ("dli_saddr", ctypes.c_void_p)]


def blasfeo_library(engine: ctypes.CDLL) -> str:
    """The file of the BLASFEO whose routines HPIPM's calls bind to in this process: a BLASFEO in the global scope
    (``LD_PRELOAD``, or loaded with ``RTLD_GLOBAL``) comes first for every library, else the engine's own (CasADi's
    wheel's). A different BLASFEO build is a different controller at the rounding level (its kernels sum in another
    order): reports name it (docs/results/acados.md measures acados' Haswell build against CasADi's generic one)."""
    libc = ctypes.CDLL(None)
    for scope in (libc, engine):
        try:
            fn = scope.blasfeo_dgemm_nt
        except AttributeError:
            continue
        info = _DlInfo()
        if libc.dladdr(ctypes.cast(fn, ctypes.c_void_p), ctypes.byref(info)) and info.dli_fname:
            return os.path.realpath(info.dli_fname.decode())
    return "unknown"


def use_simd_kernels(requested: bool) -> tuple[bool, str]:
    """Whether the AVX2 kernels go into the engine, and why (for ``aerorelay bench``)."""
    if not requested:
        return False, "AVX2 kernels switched off"
    if not cpu_has_avx2_fma():
        return False, "CPU without AVX2/FMA"
    return blasfeo_matches_avx2_kernels()


ENGINE_FLAGS = ("-O3",)  # the engine's optimization (the exported C tree's Makefile and CMake use the same)
# The simulator's engine compiles CasADi's stage code (straight-line arithmetic) at GCC's -O1, the driver and kernels
# at ENGINE_FLAGS: outputs bit-identical (IEEE arithmetic, no contraction on x86-64's baseline), an engine built in
# 2.2 s instead of 3.0 s, its preparation 1-2% slower (0.679 / 0.666 ms a step, measured 2026-12-06,
# docs/results/controller-speed.md). The C tree for the flight computer (``aerorelay codegen``) keeps -O3 throughout.
GENERATED_OPT = ('#if defined(__GNUC__) && !defined(__clang__)\n#pragma GCC push_options\n#pragma GCC optimize ("O1")\n'
                 '#endif\n', '\n#if defined(__GNUC__) && !defined(__clang__)\n#pragma GCC pop_options\n#endif\n')
SIMD_HEAD = "\n#define RTI_SIMD 1\nextern int aerorelay_simd_kernels_ran;\n"  # after blasfeo_avx2.c, before the macros


def engine_parts(spec: OcpSpec) -> tuple[str, str, str]:
    """The engine's C source in its three parts, checked against the OCP: the CasADi-generated stage and terminal
    linearization, the dimension macros, and the driver (``rti_hpipm.c``). Compiled in this order (with
    ``blasfeo_avx2.c`` and ``SIMD_HEAD`` before the macros when the AVX2 kernels go in), here and in the C tree
    ``aerorelay codegen`` writes."""
    stage, term = stage_linearization(spec, dense=True), terminal_linearization(spec, dense=True)
    check_dimensions(spec, stage, term)
    macros = {
        "RTI_N": spec.horizon, "RTI_NX": spec.nx, "RTI_NW": spec.nw, "RTI_NR": spec.n_rotors, "RTI_NS": spec.ns,
        "RTI_NG": spec.ng, "RTI_NP": spec.n_params, "RTI_NBX": len(stage_bounds(spec)[0]),
    }
    head = "".join(f"#define {k} {v}\n" for k, v in macros.items())
    driver = resources.files("aerorelay.control").joinpath("rti_hpipm.c").read_text()
    return generated_c(stage, term), head, driver


def simd_source() -> str:
    """``blasfeo_avx2.c``: BLASFEO's two hottest kernels for AVX2/FMA (see there)."""
    return resources.files("aerorelay.control").joinpath("blasfeo_avx2.c").read_text()


def build_library(spec: OcpSpec, flags: tuple[str, ...] = ENGINE_FLAGS, simd_kernels: bool = True) -> Path:
    """Generate, check, compile (once, cached) and return the engine's shared library. With
    ``simd_kernels`` (and ``use_simd_kernels``), ``blasfeo_avx2.c`` is compiled in (see there)."""
    generated, head, driver = engine_parts(spec)
    generated = GENERATED_OPT[0] + generated + GENERATED_OPT[1]
    if simd_kernels:
        head = simd_source() + SIMD_HEAD + head
    source = generated + "\n" + head + driver
    cdir = _casadi_dir()
    # keyed by the source alone: it holds every constant of the engine (the workspace, bounds and settings that are
    # not in it reach the engine at run time), so OCPs that differ only there share one library
    return shared_library(
        "nmpc_rti", source, "", flags=(*flags, f"-I{cdir / 'include'}"),
        link=(f"-L{cdir}", "-lhpipm", "-lblasfeo", f"-Wl,-rpath,{cdir}", "-lm"),
    )


def engine_settings(spec: OcpSpec, *, condensed_horizon: int = 0, iter_max: int = 50, tol_comp: float = 1e-4,
                    warm_start: int = 2, hessian_reg: float = 1e-8, ric_alg: int = 1, feedback_mode: int = 0,
                    accept_tol: float = 0.0, iter_continue: int = 0) -> np.ndarray:
    """``rti_create``'s settings vector (``rti_hpipm.c``): the horizon HPIPM solves (``condensed_horizon`` stages, or
    every one), the IPM's iteration cap, warm start, tolerance and regularization, the Riccati recursion, the
    feedback mode and the capped-iterate acceptance."""
    n2 = condensed_horizon if 0 < condensed_horizon < spec.horizon else spec.horizon
    if feedback_mode == 1 and n2 < spec.horizon:
        raise ValueError("the sensitivity feedback needs the uncondensed QP (condensed_horizon = 0)")
    return np.array([n2, iter_max, int(warm_start), tol_comp, hessian_reg, ric_alg, feedback_mode, accept_tol,
                     iter_continue], float)


def stage_bounds(spec: OcpSpec) -> tuple[np.ndarray, ...]:
    """``(idxbx, lbx, ubx, lbu, ubu)`` from ``ocp.absolute_bounds``: the bounded state entries
    and their bounds (the same at every stage k >= 1), and the motor-acceleration bounds. The
    slacks' bounds (``pi >= 0`` for k >= 1) are built into the engine."""
    lbz, ubz = absolute_bounds(spec)
    nx, nw, nr = spec.nx, spec.nw, spec.n_rotors
    s1 = slice(nx + nw, 2 * nx + nw)  # the states of stage 1
    idx = np.flatnonzero((lbz[s1] > -INF) | (ubz[s1] < INF)).astype(np.int32)
    return idx, lbz[s1][idx].copy(), ubz[s1][idx].copy(), lbz[nx : nx + nr].copy(), ubz[nx : nx + nr].copy()


class HpipmRti:
    """Owns one engine instance (HPIPM workspace + plan) inside the compiled library.

    ``prepare(P)`` linearizes at the current guess (``P``: the ``(n_params, N+1)`` parameter
    matrix); ``feedback(xa0)`` solves the QP for the measured state, applies the step, shifts the
    plan and returns the first input with an ``RtiInfo``.
    """

    def __init__(self, spec: OcpSpec, *, condensed_horizon: int = 0, iter_max: int = 50,
                 tol_comp: float = 1e-4, warm_start: int = 2, hessian_reg: float = 1e-8,
                 ric_alg: int = 1, simd_kernels: bool = True, feedback_mode: int = 0, accept_tol: float = 0.0,
                 iter_continue: int = 0):
        self.spec = spec
        self.simd_compiled, self.simd_reason = use_simd_kernels(simd_kernels)
        lib = ctypes.CDLL(str(build_library(spec, simd_kernels=self.simd_compiled)))
        lib.rti_simd_kernels_ran.restype = ctypes.c_int
        lib.rti_create.restype = ctypes.c_void_p
        lib.rti_create.argtypes = [_dp, ctypes.POINTER(ctypes.c_int), _dp, _dp, _dp, _dp]
        lib.rti_prepare.argtypes = [ctypes.c_void_p, _dp]
        lib.rti_feedback.argtypes = [ctypes.c_void_p, _dp, ctypes.c_int, _dp, ctypes.POINTER(RtiInfo)]
        lib.rti_feedback.restype = ctypes.c_int
        lib.rti_set_plan.argtypes = [ctypes.c_void_p, _dp, _dp]
        lib.rti_get_plan.argtypes = [ctypes.c_void_p, _dp, _dp, _dp, _dp]
        lib.rti_free.argtypes = [ctypes.c_void_p]
        self._lib = lib
        settings = engine_settings(spec, condensed_horizon=condensed_horizon, iter_max=iter_max, tol_comp=tol_comp,
                                   warm_start=warm_start, hessian_reg=hessian_reg, ric_alg=ric_alg,
                                   feedback_mode=feedback_mode, accept_tol=accept_tol, iter_continue=iter_continue)
        self._keep = list(stage_bounds(spec))
        self._mem = lib.rti_create(_ptr(settings), self._keep[0].ctypes.data_as(ctypes.POINTER(ctypes.c_int)),
                                   *(_ptr(a) for a in self._keep[1:]))
        if not self._mem:
            raise MemoryError("could not allocate the HPIPM RTI engine's memory")
        N, nx, nw = spec.horizon, spec.nx, spec.nw
        self._plans = [np.zeros((N + 1) * nx), np.zeros(N * nw), np.zeros((N + 1) * nx), np.zeros(N * nw)]
        self._u = np.zeros(spec.n_rotors)
        self.info = RtiInfo()

    def __del__(self):
        mem, lib = getattr(self, "_mem", None), getattr(self, "_lib", None)
        if mem and lib is not None:
            lib.rti_free(mem)
            self._mem = None

    def blasfeo_library(self) -> str:
        """The file of the BLASFEO that HPIPM's calls bind to in this process (``blasfeo_library``)."""
        return blasfeo_library(self._lib)

    def simd_kernels_ran(self) -> int:
        """1 if the AVX2 BLASFEO kernels have run in this process, 0 if not (after solves: compiled
        in but not used, e.g. libblasfeo was bound earlier by another user), -1 if not compiled in."""
        return int(self._lib.rti_simd_kernels_ran())

    def set_plan(self, X: np.ndarray, W: np.ndarray):
        """Set the guess from ``X (nx, N+1)`` and ``W (nw, N)``."""
        N, nx, nw = self.spec.horizon, self.spec.nx, self.spec.nw
        _check_shape("X", X, (nx, N + 1))
        _check_shape("W", W, (nw, N))
        Xf = np.asarray(X, float).reshape(-1, order="F")
        Wf = np.asarray(W, float).reshape(-1, order="F")
        self._lib.rti_set_plan(self._mem, _ptr(Xf), _ptr(Wf))

    def plan(self) -> tuple[np.ndarray, ...]:
        """``(Xb, Wb, X, W)``: the current guess and the last solution before its shift."""
        self._lib.rti_get_plan(self._mem, *(_ptr(a) for a in self._plans))
        N, nx, nw = self.spec.horizon, self.spec.nx, self.spec.nw
        shapes = [(nx, N + 1), (nw, N), (nx, N + 1), (nw, N)]
        return tuple(a.reshape(s, order="F").copy() for a, s in zip(self._plans, shapes, strict=True))

    def prepare(self, P: np.ndarray) -> None:
        """Preparation phase at the current guess (the C side reads ``P`` during the call only)."""
        _check_shape("P", P, (self.spec.n_params, self.spec.horizon + 1))
        self._lib.rti_prepare(self._mem, _ptr(np.asfortranarray(P, float)))

    def feedback(self, xa0: np.ndarray, shift: bool = True) -> tuple[np.ndarray, RtiInfo]:
        """Feedback phase for the measured state ``xa0``; returns ``(u0, info)``."""
        _check_shape("xa0", xa0, (self.spec.nx,))
        x = np.ascontiguousarray(xa0, float)
        self._lib.rti_feedback(self._mem, _ptr(x), int(shift), _ptr(self._u), ctypes.byref(self.info))
        return self._u.copy(), self.info


def _check_shape(name: str, a, shape: tuple[int, ...]):
    if np.shape(a) != shape:
        raise ValueError(f"{name} has shape {np.shape(a)}, the OCP needs {shape}")


def _ptr(a: np.ndarray):
    if a.dtype != np.float64 or not (a.flags.c_contiguous or a.flags.f_contiguous):
        raise TypeError(f"engine buffers must be contiguous float64 arrays, got {a.dtype} "
                        f"(contiguous: {a.flags.c_contiguous or a.flags.f_contiguous})")
    return a.ctypes.data_as(_dp)
