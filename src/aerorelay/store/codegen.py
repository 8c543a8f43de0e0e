"""Compile C code (CasADi-generated or ours) to shared libraries, cached on disk.

The cache folder is ``$AERORELAY_CACHE`` or ``~/.cache/aerorelay``; a library is keyed by a hash
of its complete C source (which embeds the expression graph and every constant in it), the
caller's key (what the library depends on beyond its source; the generated engines have none),
the CasADi version and the compiler flags, so any change to the model or the code generating it
builds a new library, and two models with one source (OCPs that differ only in run-time bounds,
e.g. the workspace) share one. When no C compiler is available the caller falls back (a warning is logged).
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
import numpy as np

from .cache import cache_dir, cache_lock, entry_is_intact, publish_checked

log = logging.getLogger(__name__)
CASADI_VERSION: str = getattr(ca, "__version__", "unknown")


class CompileError(RuntimeError):
    """No C compiler, or the compiler rejected the source."""


def generated_c(*funs: ca.Function, name: str = "gen.c") -> str:
    """C source of ``funs`` from CasADi's code generator (no header, no main); ``name``: the file's, which prefixes
    the generated helpers (two generated sources in one program need two names)."""
    with tempfile.TemporaryDirectory() as tmp:
        cg = ca.CodeGenerator(name, {"with_header": False})
        for f in funs:
            cg.add(f)
        cg.generate(tmp + os.sep)
        return (Path(tmp) / name).read_text()


def shared_library(name: str, source: str, key: str, *, flags: tuple[str, ...] = ("-O2",),
                   link: tuple[str, ...] = ()) -> Path:
    """Path of ``source`` compiled to a shared library, built once and cached; raises CompileError.

    Concurrent builders (dask workers starting together) serialize on a file lock in the cache
    folder; the library is compiled in a temporary folder inside the cache folder (same
    filesystem) and published with ``os.replace``, so nobody ever loads a half-written file.
    """
    digest = hashlib.sha256(f"{source}|{key}|{CASADI_VERSION}|{flags}|{link}".encode()).hexdigest()[:16]
    folder = cache_dir()
    lib = folder / f"{name}_{digest}.so"
    if entry_is_intact(lib):
        return lib
    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        raise CompileError("no C compiler (gcc or cc) on PATH")
    with cache_lock(lib):
        if entry_is_intact(lib):  # another process built it while we waited
            return lib
        if lib.exists():
            log.warning("cached library %s is corrupt or unverified: rebuilt", lib)
        with tempfile.TemporaryDirectory(dir=folder, prefix=f".{name}_") as tmp:
            src, out = Path(tmp) / f"{name}.c", Path(tmp) / f"{name}.so"
            src.write_text(source)
            res = subprocess.run([cc, *flags, "-shared", "-fPIC", "-o", str(out), str(src), *link],
                                 capture_output=True, text=True)
            if res.returncode != 0:
                raise CompileError(f"compiling {name} failed: {res.stderr[-2000:]}")
            publish_checked(out, lib)
    return lib


def compiled(fun: ca.Function, key: str, *, flags: tuple[str, ...] = ("-O2",)) -> ca.Function:
    """Return ``fun`` compiled to a shared library (cached by ``key``), or ``fun`` itself on failure."""
    try:
        lib = shared_library(fun.name(), generated_c(fun), key, flags=flags)
    except CompileError as err:
        log.warning("%s runs in CasADi's virtual machine (slower): %s", fun.name(), err)
        return fun
    return ca.external(fun.name(), str(lib))


class BufferedCall:
    """A CasADi function of one dense input and one dense output called through its buffer
    interface (no DM conversions: < 1 us of overhead): fill ``arg`` in place, call, read the
    returned ``res`` (overwritten by the next call)."""

    def __init__(self, fun: ca.Function):
        if fun.n_in() != 1 or fun.n_out() != 1:
            raise ValueError(f"{fun.name()}: a buffered call needs one input and one output, got {fun.n_in()} and {fun.n_out()}")
        if not (fun.sparsity_in(0).is_dense() and fun.sparsity_out(0).is_dense()):
            raise ValueError(f"{fun.name()}: a buffered call needs a dense input and output (ca.densify): the buffer "
                             "holds the nonzeros only, a sparse one would shift the values")
        self.arg, self.res = np.zeros(fun.nnz_in(0)), np.zeros(fun.nnz_out(0))
        self._buffer, self._eval = fun.buffer()
        # CasADi's typemap takes the memoryview as (pointer, size); its stub lists both arguments
        self._buffer.set_arg(0, memoryview(self.arg))  # type: ignore[call-arg, arg-type]
        self._buffer.set_res(0, memoryview(self.res))  # type: ignore[call-arg, arg-type]

    def __call__(self) -> np.ndarray:
        self._eval()
        return self.res
