"""A fingerprint of what a scenario builds (``assembly.parts.build``): every number, array, flag and name held by
the built parts, walked through objects, containers and closures, not the plain configuration handed in (pydantic
models) and not memory handles. Two builds of one file have one fingerprint; a setting that changes nothing built
leaves it as it was (``test_no_dead_setting``)."""

from __future__ import annotations

import functools
import hashlib
import types

import numpy as np
from pydantic import BaseModel

HANDLES = frozenset({"_mem"})  # a compiled function's C memory address: differs per build, not a setting


def fingerprint(obj: object) -> str:
    h = hashlib.sha256()
    seen: set[int] = set()

    def walk(o: object, depth: int) -> None:
        if depth > 40:
            return
        if o is None or isinstance(o, (bool, int, float, str, bytes, np.generic)):
            h.update(repr(o).encode())
            return
        if isinstance(o, np.ndarray):
            h.update(o.tobytes() if o.dtype != object else repr(o).encode())
            return
        if id(o) in seen:
            return
        seen.add(id(o))
        if isinstance(o, BaseModel):
            return  # plain data handed to a part, not what was built from it
        module = type(o).__module__ or ""
        if isinstance(o, dict):
            for k in sorted(o, key=repr):
                if k not in HANDLES:
                    h.update(repr(k).encode())
                    walk(o[k], depth + 1)
            return
        if isinstance(o, (list, tuple)):
            for x in o:
                walk(x, depth + 1)
            return
        if isinstance(o, (set, frozenset)):
            for x in sorted(o, key=repr):
                walk(x, depth + 1)
            return
        if isinstance(o, functools.partial):
            walk(o.func, depth + 1)
            walk(o.args, depth + 1)
            walk(o.keywords, depth + 1)
            return
        if isinstance(o, types.MethodType):
            walk(o.__self__, depth + 1)
            o = o.__func__
        if isinstance(o, types.FunctionType):
            h.update(o.__qualname__.encode())
            for cell in o.__closure__ or ():
                try:
                    walk(cell.cell_contents, depth + 1)
                except ValueError:  # an empty cell
                    pass
            return
        h.update(type(o).__qualname__.encode())
        if not module.startswith("aerorelay"):
            return  # a library's object (CasADi's functions): what it was built from is in our parts
        attrs = getattr(o, "__dict__", None)
        if attrs is not None:
            walk(attrs, depth + 1)
        for name in getattr(type(o), "__slots__", ()):
            if hasattr(o, name):
                walk(getattr(o, name), depth + 1)
        if attrs is None and hasattr(type(o), "__dataclass_fields__"):
            for name in o.__dataclass_fields__:  # type: ignore[attr-defined]
                walk(getattr(o, name), depth + 1)

    walk(obj, 0)
    return h.hexdigest()
