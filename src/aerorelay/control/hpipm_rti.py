"""The RTI step as one compiled C call: CasADi-generated stage linearization + HPIPM.

``rti_hpipm.c`` is appended to the C code CasADi generates for the per-stage linearization of
``ocp.py`` and linked against the HPIPM and BLASFEO libraries that ship in CasADi's wheel (no
extra dependency). Compared with ``casadi.conic('hpipm')`` this keeps HPIPM's structures alive
between steps instead of rebuilding them on every call, drops the two variable blocks the
conic route fixes by equal bounds (initial state, stage-0 slack), can partially condense the
horizon, and leaves one Python -> C call per control step.
"""

from __future__ import annotations

import ctypes
import platform
from importlib import resources
from pathlib import Path

import casadi as ca
import numpy as np

from .codegen import generated_c, shared_library
from .linearization import stage_linearization, terminal_linearization
from .ocp import INF, NP, OcpSpec, ParamIndex, absolute_bounds

_dp = ctypes.POINTER(ctypes.c_double)


def _casadi_dir() -> Path:
    return Path(ca.__file__).parent


def cpu_has_avx2_fma() -> bool:
    """Whether this (Linux, x86-64) CPU advertises AVX2 and FMA (False where it cannot be told)."""
    try:
        flags = Path("/proc/cpuinfo").read_text().split()
    except OSError:
        return False
    return platform.machine() in ("x86_64", "AMD64") and "avx2" in flags and "fma" in flags


def build_library(spec: OcpSpec, flags: tuple[str, ...] = ("-O3",), simd_kernels: bool = True) -> Path:
    """Generate, compile (once, cached) and return the engine's shared library. With
    ``simd_kernels`` and an AVX2/FMA CPU, ``blasfeo_avx2.c`` is compiled in (see there)."""
    nr = spec.vehicle.n_rotors
    idxbx = stage_bounds(spec)[0]
    macros = {
        "RTI_N": spec.horizon, "RTI_NX": spec.nx, "RTI_NW": spec.nw, "RTI_NR": nr, "RTI_NP": NP,
        "RTI_NBX": len(idxbx), "RTI_CONSTRAINED": int(spec.constrained), "RTI_MU_INDEX": ParamIndex.mu,
    }
    head = "".join(f"#define {k} {v}\n" for k, v in macros.items())
    here = resources.files("aerorelay.control")
    driver = here.joinpath("rti_hpipm.c").read_text()
    if simd_kernels and cpu_has_avx2_fma():
        head = here.joinpath("blasfeo_avx2.c").read_text() + "\n#define RTI_SIMD 1\nextern int aerorelay_simd_kernels_ran;\n" + head
    source = generated_c(stage_linearization(spec, dense=True), terminal_linearization(spec, dense=True)) + "\n" + head + driver
    cdir = _casadi_dir()
    return shared_library(
        "nmpc_rti", source, spec.key(), flags=(*flags, f"-I{cdir / 'include'}"),
        link=(f"-L{cdir}", "-lhpipm", "-lblasfeo", f"-Wl,-rpath,{cdir}", "-lm"),
    )


def stage_bounds(spec: OcpSpec) -> tuple[np.ndarray, ...]:
    """``(idxbx, lbx, ubx, lbu, ubu)`` from ``ocp.absolute_bounds``: the bounded state entries
    and their bounds (the same at every stage k >= 1), and the motor-acceleration bounds. The
    slack's bound (``pi >= 0`` for k >= 1) is built into the engine."""
    lbz, ubz = absolute_bounds(spec)
    nx, nw, nr = spec.nx, spec.nw, spec.vehicle.n_rotors
    s1 = slice(nx + nw, 2 * nx + nw)  # the states of stage 1
    idx = np.flatnonzero((lbz[s1] > -INF) | (ubz[s1] < INF)).astype(np.int32)
    return idx, lbz[s1][idx].copy(), ubz[s1][idx].copy(), lbz[nx : nx + nr].copy(), ubz[nx : nx + nr].copy()


class HpipmRti:
    """Owns one engine instance (HPIPM workspace + plan) inside the compiled library.

    ``step(xa0, P)`` linearizes at the current guess, solves the QP, applies the step, shifts the
    plan and returns the first input. ``P`` is the ``(NP, N+1)`` parameter matrix.
    """

    INFO = 6

    def __init__(self, spec: OcpSpec, *, condensed_horizon: int = 0, iter_max: int = 50,
                 tol_comp: float = 1e-4, warm_start: int = 2, hessian_reg: float = 1e-8,
                 ric_alg: int = 1, simd_kernels: bool = True):
        self.spec = spec
        lib = ctypes.CDLL(str(build_library(spec, simd_kernels=simd_kernels)))
        lib.rti_simd_kernels_ran.restype = ctypes.c_int
        lib.rti_create.restype = ctypes.c_void_p
        lib.rti_create.argtypes = [_dp, ctypes.POINTER(ctypes.c_int), _dp, _dp, _dp, _dp]
        lib.rti_step.argtypes = [ctypes.c_void_p, _dp, _dp, ctypes.c_int, _dp, _dp]
        lib.rti_step.restype = ctypes.c_int
        lib.rti_set_plan.argtypes = [ctypes.c_void_p, _dp, _dp]
        lib.rti_get_plan.argtypes = [ctypes.c_void_p, _dp, _dp, _dp, _dp]
        lib.rti_free.argtypes = [ctypes.c_void_p]
        self._lib = lib
        nr = spec.vehicle.n_rotors
        n2 = condensed_horizon if 0 < condensed_horizon < spec.horizon else spec.horizon
        settings = np.array([n2, iter_max, int(warm_start), tol_comp, hessian_reg, ric_alg], float)
        self._keep = list(stage_bounds(spec))
        self._mem = lib.rti_create(_ptr(settings), self._keep[0].ctypes.data_as(ctypes.POINTER(ctypes.c_int)),
                                   *(_ptr(a) for a in self._keep[1:]))
        if not self._mem:
            raise MemoryError("could not create the HPIPM RTI engine")
        N, nx, nw = spec.horizon, spec.nx, spec.nw
        self._plans = [np.zeros((N + 1) * nx), np.zeros(N * nw), np.zeros((N + 1) * nx), np.zeros(N * nw)]
        self._u = np.zeros(nr)
        self._info = np.zeros(self.INFO)

    def __del__(self):
        mem, lib = getattr(self, "_mem", None), getattr(self, "_lib", None)
        if mem and lib is not None:
            lib.rti_free(mem)
            self._mem = None

    def simd_kernels_ran(self) -> int:
        """1 if the AVX2 BLASFEO kernels have run in this process, 0 if not (after solves: compiled
        in but not used, e.g. libblasfeo was bound earlier by another user), -1 if not compiled in."""
        return int(self._lib.rti_simd_kernels_ran())

    def set_plan(self, X: np.ndarray, W: np.ndarray):
        """Set the guess from ``X (nx, N+1)`` and ``W (nw, N)``."""
        Xf = np.asarray(X, float).reshape(-1, order="F")
        Wf = np.asarray(W, float).reshape(-1, order="F")
        self._lib.rti_set_plan(self._mem, _ptr(Xf), _ptr(Wf))

    def plan(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(Xb, Wb, X, W)``: the current guess and the last solution before its shift."""
        self._lib.rti_get_plan(self._mem, *(_ptr(a) for a in self._plans))
        N, nx, nw = self.spec.horizon, self.spec.nx, self.spec.nw
        shapes = [(nx, N + 1), (nw, N), (nx, N + 1), (nw, N)]
        return tuple(a.reshape(s, order="F").copy() for a, s in zip(self._plans, shapes))

    def step(self, xa0: np.ndarray, P: np.ndarray, shift: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Run one RTI; returns ``(u0, info)`` with info = ok, status, iterations, slack max,
        preparation ms, QP ms (see ``rti_step`` in rti_hpipm.c)."""
        x = np.ascontiguousarray(xa0, float)
        Pf = np.asfortranarray(P, float)
        self._lib.rti_step(self._mem, _ptr(x), _ptr(Pf), int(shift), _ptr(self._u), _ptr(self._info))
        return self._u.copy(), self._info.copy()


def _ptr(a: np.ndarray):
    assert a.dtype == np.float64 and (a.flags.c_contiguous or a.flags.f_contiguous)
    return a.ctypes.data_as(_dp)
