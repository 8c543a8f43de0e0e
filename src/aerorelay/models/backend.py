"""Tiny numeric/symbolic shim so one formula serves numpy arrays and CasADi symbols.

Conventions: numpy vectors are arrays whose *last* axis has length 3 (batched ``(..., 3)``);
CasADi vectors are 3x1 column expressions. Rotation matrices are ``(..., 3, 3)`` or 3x3.
"""

from __future__ import annotations

from types import SimpleNamespace

import casadi as ca
import numpy as np

_SYMBOLIC = (ca.SX, ca.MX)


def is_symbolic(*args) -> bool:
    """True when any argument is a CasADi SX/MX expression."""
    return any(isinstance(a, _SYMBOLIC) for a in args)


def _np_matvec(R, v):
    return np.einsum("...ij,...j->...i", R, v)


def _np_matTvec(R, v):
    return np.einsum("...ji,...j->...i", R, v)


_NUMPY = SimpleNamespace(
    sqrt=np.sqrt,
    sin=np.sin,
    cos=np.cos,
    tan=np.tan,
    arccos=lambda x: np.arccos(np.clip(x, -1.0, 1.0)),
    log2=np.log2,
    log10=np.log10,
    exp=np.exp,
    log1p=np.log1p,
    dot=lambda a, b: np.sum(np.asarray(a) * np.asarray(b), axis=-1),
    norm=lambda a: np.linalg.norm(a, axis=-1),
    matvec=_np_matvec,
    matTvec=_np_matTvec,
    cross=lambda a, b: np.cross(a, b),
    component=lambda v, i: np.asarray(v)[..., i],
    vector=lambda *c: np.stack(np.broadcast_arrays(*c), axis=-1),
    where=np.where,
    fmax=np.maximum,
)

_CASADI = SimpleNamespace(
    sqrt=ca.sqrt,
    sin=ca.sin,
    cos=ca.cos,
    tan=ca.tan,
    arccos=ca.acos,
    log2=lambda x: ca.log(x) / np.log(2.0),
    log10=ca.log10,
    exp=ca.exp,
    log1p=ca.log1p,
    dot=ca.dot,
    norm=ca.norm_2,
    matvec=lambda R, v: ca.mtimes(R, v),
    matTvec=lambda R, v: ca.mtimes(R.T, v),
    cross=ca.cross,
    component=lambda v, i: v[i],
    vector=lambda *c: ca.vertcat(*c),
    where=ca.if_else,
    fmax=ca.fmax,
)


def ops(*args) -> SimpleNamespace:
    """Return the operation namespace (numpy or CasADi) matching the arguments."""
    return _CASADI if is_symbolic(*args) else _NUMPY
