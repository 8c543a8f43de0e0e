"""Compile CasADi functions to C once and cache the shared library on disk.

The cache folder is ``$AERORELAY_CACHE`` or ``~/.cache/aerorelay``; a library is keyed by a hash
of the function's serialized expression graph, the caller's key, the CasADi version and the
compiler flags, so any change to the model or the code generating it builds a new library. When no C compiler is available the
in-memory (virtual machine) function is returned and a warning is logged.
"""

from __future__ import annotations

import hashlib
import logging
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import casadi as ca

log = logging.getLogger(__name__)


def cache_dir() -> Path:
    return Path(os.environ.get("AERORELAY_CACHE", Path.home() / ".cache" / "aerorelay"))


def compiled(fun: ca.Function, key: str, *, flags: tuple[str, ...] = ("-O2",)) -> ca.Function:
    """Return ``fun`` compiled to a shared library (cached by ``key``), or ``fun`` itself on failure."""
    graph = hashlib.sha256(fun.serialize().encode()).hexdigest()
    digest = hashlib.sha256(f"{graph}|{key}|{ca.__version__}|{flags}|{fun.name()}".encode()).hexdigest()[:16]
    name = f"{fun.name()}_{digest}"
    lib = cache_dir() / f"{name}.so"
    if not lib.exists():
        cc = shutil.which("gcc") or shutil.which("cc")
        if cc is None:
            log.warning("no C compiler found: %s runs in CasADi's virtual machine (slower)", fun.name())
            return fun
        lib.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory() as tmp:
            src = Path(tmp) / f"{name}.c"
            cg = ca.CodeGenerator(src.name, {"with_header": False})
            cg.add(fun)
            cg.generate(tmp + os.sep)
            out = Path(tmp) / f"{name}.so"
            res = subprocess.run([cc, *flags, "-shared", "-fPIC", "-o", str(out), str(src)], capture_output=True, text=True)
            if res.returncode != 0:
                log.warning("compiling %s failed, using the virtual machine: %s", name, res.stderr[-2000:])
                return fun
            shutil.move(str(out), lib)  # atomic within one filesystem; concurrent builders are harmless
    return ca.external(fun.name(), str(lib))
