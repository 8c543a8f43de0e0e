"""The on-disk library cache (concurrent builders publish one complete library) and buffered calls."""

import ctypes
import subprocess
import sys

import casadi as ca
import numpy as np
import pytest

from aerorelay.store.codegen import BufferedCall


def test_concurrent_builders_publish_one_complete_library(tmp_path):
    code = ("import sys; from aerorelay.store.codegen import shared_library\n"
            "src = 'double twice(double x) { return 2 * x; }\\n' + '/* pad */\\n' * 20000\n"
            "print(shared_library('race', src, 'k'))\n")
    env = {"AERORELAY_CACHE": str(tmp_path), "PATH": "/usr/bin:/bin"}
    procs = [subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True, env=env) for _ in range(4)]
    paths = {p.communicate(timeout=120)[0].strip() for p in procs}
    assert all(p.returncode == 0 for p in procs)
    assert len(paths) == 1
    lib = ctypes.CDLL(paths.pop())
    lib.twice.restype, lib.twice.argtypes = ctypes.c_double, [ctypes.c_double]
    assert lib.twice(21.0) == 42.0
    leftovers = [f.name for f in tmp_path.iterdir() if not f.name.endswith((".so", ".so.sha256", ".lock"))]
    assert leftovers == []  # the temporary build folders are gone


def test_buffered_call_matches_the_function_and_refuses_a_sparse_output():
    x = ca.SX.sym("x", 3)
    dense = ca.Function("f", [x], [ca.densify(ca.vertcat(ca.sumsqr(x), 0 * x[0], 2 * x))])
    call = BufferedCall(dense)
    call.arg[:] = [1.0, -2.0, 0.5]
    np.testing.assert_array_equal(call(), np.array(dense([1.0, -2.0, 0.5])).ravel())
    sparse = ca.Function("g", [x], [ca.vertcat(ca.sumsqr(x), ca.SX(1, 1), 2 * x)])  # a structural zero
    with pytest.raises(ValueError, match="dense"):
        BufferedCall(sparse)
    with pytest.raises(ValueError, match="one input and one output"):
        BufferedCall(ca.Function("h", [x], [x, x]))
