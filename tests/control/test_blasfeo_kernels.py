"""The AVX2 kernels of blasfeo_avx2.c against CasADi's own (generic) BLASFEO kernels."""

import ctypes
import os

import numpy as np
import pytest

from aerorelay.assembly import parse_scenario
from aerorelay.assembly.parts import ocp_spec
from aerorelay.control.blasfeo_contract import contract_violations
from aerorelay.control.hpipm_rti import HpipmRti, _casadi_dir, cpu_has_avx2_fma

if not cpu_has_avx2_fma():
    if os.environ.get("AERORELAY_REQUIRE_AVX2") == "1":  # CI sets it on a CPU that has them: the detection must agree
        raise RuntimeError("AERORELAY_REQUIRE_AVX2=1 but cpu_has_avx2_fma() says no: the AVX2 kernels would go untested")
    pytestmark = pytest.mark.skip(reason="CPU without AVX2/FMA: kernels not compiled in")

dp = ctypes.POINTER(ctypes.c_double)


def _p(a):
    return a.ctypes.data_as(dp)


@pytest.fixture(scope="module")
def kernels():
    ours = HpipmRti(ocp_spec(parse_scenario({})))._lib
    generic = ctypes.CDLL(str(_casadi_dir() / "libblasfeo.so"))
    return ours, generic


def _scalars(rng):
    return np.array([rng.normal()]), np.array([rng.choice([0.0, 1.0, rng.normal()])])


@pytest.mark.parametrize("kmax", [0, 1, 2, 3, 4, 7, 24, 31])
def test_dgemm_nt_matches_generic(kernels, kmax):
    rng = np.random.default_rng(kmax)
    for _ in range(20):
        A, B, C = rng.normal(size=4 * kmax + 4), rng.normal(size=4 * kmax + 4), rng.normal(size=16)
        alpha, beta = _scalars(rng)
        out = []
        for lib in kernels:
            D = np.full(16, np.nan)
            lib.kernel_dgemm_nt_4x4_lib4(ctypes.c_int(kmax), _p(alpha), _p(A), _p(B), _p(beta), _p(C), _p(D))
            out.append(D)
        a, b = A[: 4 * kmax].reshape(kmax, 4).T, B[: 4 * kmax].reshape(kmax, 4).T  # 4 x k panels
        expected = (alpha[0] * a @ b.T + beta[0] * C.reshape(4, 4).T).T.ravel()
        np.testing.assert_allclose(out[0], out[1], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(out[0], expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("offset", [0, 1, 2, 3])
@pytest.mark.parametrize("kmax", [0, 1, 2, 5, 8, 13, 30])
def test_dgemm_nn_matches_generic(kernels, kmax, offset):
    rng = np.random.default_rng(100 * kmax + offset)
    sdb = 8  # panel stride (columns allocated per panel)
    panels = (offset + kmax) // 4 + 2
    for _ in range(10):
        A, C = rng.normal(size=4 * kmax + 4), rng.normal(size=16)
        B = rng.normal(size=panels * 4 * sdb)
        alpha, beta = _scalars(rng)
        out = []
        for lib in kernels:
            D = np.full(16, np.nan)
            lib.kernel_dgemm_nn_4x4_lib4(ctypes.c_int(kmax), _p(alpha), _p(A), ctypes.c_int(offset), _p(B),
                                         ctypes.c_int(sdb), _p(beta), _p(C), _p(D))
            out.append(D)
        rows = [offset + l for l in range(kmax)]
        b = np.array([[B[(r // 4) * 4 * sdb + r % 4 + 4 * j] for j in range(4)] for r in rows]).reshape(kmax, 4)
        a = A[: 4 * kmax].reshape(kmax, 4).T
        expected = (alpha[0] * a @ b + beta[0] * C.reshape(4, 4).T).T.ravel()
        if kmax > 0 or offset == 0:  # the generic kernel reads one partial panel even when kmax = 0
            np.testing.assert_allclose(out[0], out[1], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(out[0], expected, rtol=1e-12, atol=1e-12)


def test_our_kernels_and_casadis_compute_the_written_contracts(kernels):
    """Every kernel blasfeo_avx2.c replaces, ours and CasADi's, against its numpy reference (the
    engine compiles ours in only when CasADi's pass this same check)."""
    ours, generic = kernels
    assert contract_violations(ours) == []
    assert contract_violations(generic) == []


def test_contract_check_catches_another_contract(kernels):
    """A kernel with the same arguments that computes something else is reported: here BLASFEO's
    dsyrk (the lower triangle of A B^T only) standing in for dgemm_nt."""
    ours, generic = kernels

    class Swapped:
        def __getattr__(self, name):
            if name == "kernel_dgemm_nt_4x4_lib4":
                return generic.kernel_dsyrk_nt_l_4x4_lib4
            return getattr(ours, name)

    bad = contract_violations(Swapped())
    assert len(bad) == 1 and bad[0].startswith("kernel_dgemm_nt_4x4_lib4")


def _one_step_in_a_fresh_process(env: dict | None = None, before_step: str = "") -> str:
    """A fresh process that loads the engine first and steps the NMPC once at hover: what it prints (the AVX2
    kernels' flag, then the route). ``before_step``: a line run between the engine's load and its first solve."""
    import subprocess
    import sys

    code = ("import numpy as np\n"
            "from aerorelay.assembly import parse_scenario\n"
            "from aerorelay.control.nmpc import NMPC\n"
            "from aerorelay.assembly.parts import ocp_spec, weight_parameters\n"
            "sc = parse_scenario({})\n"
            "spec = ocp_spec(sc)\n"
            "c = NMPC(spec)\n"
            "x = spec.vehicle.hover_state(np.array([0.0, 0.0, 3.0]))\n"
            f"{before_step}"
            "P = spec.params.matrix(spec.horizon + 1, {'p_ref': [0.5, 0.0, 3.0], 'v_ref': 0.0, 'rho_d': [0, 0, 1.0], 'psi_ref': 0.0,\n"
            "    'p2': [2.0, 1.0, 3.0], 'mu': 0.2, **weight_parameters(sc, spec)})\n"
            "assert c.step(x, np.zeros(6), P).ok\n"
            "print(c.engine.rti.simd_kernels_ran(), c.route())\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout


def test_hpipm_uses_them_when_loaded_first():
    """In a fresh process that loads the engine first, HPIPM's solves run the AVX2 kernels."""
    out = _one_step_in_a_fresh_process(before_step="assert c.engine.rti.simd_kernels_ran() == 0\n")
    assert out.startswith("1 ") and "AVX2 BLASFEO kernels" in out


def test_the_route_names_the_blasfeo_hpipm_runs_on(tmp_path):
    """A BLASFEO put first (LD_PRELOAD: how a Haswell build, e.g. acados', replaces CasADi's generic one for HPIPM,
    docs/results/acados.md) is what HPIPM's calls bind to: the route names its file, and the AVX2 kernels compiled into
    the engine do not run (the preloaded library calls its own). Here the preloaded file is a copy of CasADi's."""
    import os
    import shutil

    from aerorelay.control.hpipm_rti import _casadi_dir

    copy = tmp_path / "libblasfeo.so.0"
    shutil.copy(_casadi_dir() / "libblasfeo.so.0", copy)
    for preload, library in ((None, os.path.realpath(_casadi_dir() / "libblasfeo.so.0")), (str(copy), str(copy))):
        env = {k: v for k, v in os.environ.items() if k != "LD_PRELOAD"} | ({"LD_PRELOAD": preload} if preload else {})
        out = _one_step_in_a_fresh_process(env)
        assert f"BLASFEO {library})" in out, out
        if preload and out.split()[0] != "-1":  # compiled in (an AVX2 CPU): bound to the copy's own kernels
            assert out.startswith("0 "), out
