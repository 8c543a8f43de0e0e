"""The on-disk library cache: concurrent builders publish one complete library."""

import ctypes
import subprocess
import sys


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
