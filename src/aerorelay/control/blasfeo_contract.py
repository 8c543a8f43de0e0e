"""What each BLASFEO kernel that ``blasfeo_avx2.c`` replaces computes, as numpy references.

``blasfeo_avx2.c`` overrides BLASFEO's generic 4 x 4 kernels by symbol (a kernel with another
contract would silently compute something else); it is only compiled in
when CasADi's libblasfeo computes exactly these contracts (``hpipm_rti.check_blasfeo_in_this_process``
runs every ``KERNEL_CONTRACTS`` entry on it), and ``tests/control/test_blasfeo_kernels.py`` holds
our kernels to the same references and to CasADi's kernels. Storage: a 4 x k *panel* holds
element ``(i, l)`` at ``[i + 4 l]``; a k x 4 *block* of a panel-major matrix starts at row
``offset`` of a panel, panels ``4 sd`` doubles apart, element ``(r, j)`` at
``[(offset + r) // 4 * 4 sd + (offset + r) % 4 + 4 j]`` from the panel's start.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable

import numpy as np

_dp = ctypes.POINTER(ctypes.c_double)
SD = 8  # panel stride of the blocks the checks build


def ptr(a: np.ndarray):
    return a.ctypes.data_as(_dp)


def panel(rng, k: int) -> tuple[np.ndarray, np.ndarray]:
    """A 4 x k panel (one spare column: kernels may read ahead) and its matrix."""
    a = rng.normal(size=4 * k + 4)
    return a, a[: 4 * k].reshape(k, 4).T


def block(rng, offset: int, k: int) -> tuple[np.ndarray, np.ndarray]:
    """A panel-major buffer and the k x 4 block at row ``offset`` of its first panel."""
    buf = rng.normal(size=((offset + k) // 4 + 2) * 4 * SD)
    rows = offset + np.arange(k)
    index = (rows // 4 * 4 * SD + rows % 4)[:, None] + 4 * np.arange(4)[None, :]
    return buf, buf[index] if k else np.zeros((0, 4))


def square(m: np.ndarray) -> np.ndarray:
    """A 4 x 4 panel's matrix."""
    return m.reshape(4, 4).T


def gemm_nt(lib, rng, k: int, offset: int = 0) -> float:
    """``D = alpha A B^T + beta C``, A and B 4 x k panels."""
    (a, A), (b, B) = panel(rng, k), panel(rng, k)
    C, D, alpha, beta = rng.normal(size=16), np.full(16, np.nan), rng.normal(size=1), rng.normal(size=1)
    lib.kernel_dgemm_nt_4x4_lib4(ctypes.c_int(k), ptr(alpha), ptr(a), ptr(b), ptr(beta), ptr(C), ptr(D))
    return float(np.max(np.abs(square(D) - (alpha[0] * A @ B.T + beta[0] * square(C)))))


def gemm_nn(lib, rng, k: int, offset: int = 0) -> float:
    """``D = alpha A B + beta C``, A a 4 x k panel, B a k x 4 block."""
    a, A = panel(rng, k)
    buf, B = block(rng, offset, k)
    C, D, alpha, beta = rng.normal(size=16), np.full(16, np.nan), rng.normal(size=1), rng.normal(size=1)
    lib.kernel_dgemm_nn_4x4_lib4(ctypes.c_int(k), ptr(alpha), ptr(a), ctypes.c_int(offset), ptr(buf), ctypes.c_int(SD),
                                 ptr(beta), ptr(C), ptr(D))
    return float(np.max(np.abs(square(D) - (alpha[0] * A @ B + beta[0] * square(C)))))


# kernel name -> (reference check, sizes k, offsets): each returns the largest deviation
KERNEL_CONTRACTS: dict[str, tuple[Callable, tuple[int, ...], tuple[int, ...]]] = {
    "kernel_dgemm_nt_4x4_lib4": (gemm_nt, (0, 1, 2, 5, 24, 31), (0,)),
    "kernel_dgemm_nn_4x4_lib4": (gemm_nn, (1, 2, 5, 24, 31), (0, 1, 2, 3)),
}


def contract_violations(lib, tol: float = 1e-8) -> list[str]:
    """The kernels of ``lib`` (a ctypes library) that do not compute their ``KERNEL_CONTRACTS`` entry."""
    rng = np.random.default_rng(0)
    bad = []
    for name, (check, sizes, offsets) in KERNEL_CONTRACTS.items():
        errors = [check(lib, rng, k, off) for k in sizes for off in offsets]
        if not all(e <= tol for e in errors):  # (NaN fails too)
            bad.append(f"{name} (deviation {max(errors):.3g})")
    return bad
