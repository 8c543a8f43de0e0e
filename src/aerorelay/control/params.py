"""Named per-stage parameter vector: one definition builds the CasADi symbol and the numeric matrix.

``StageParams([("p_ref", 3), ("mu", 1), ...])`` lays the fields out one after the other. The
OCP reads its symbol through ``unpack(p)`` (a dict of named slices) and the controller builds
the ``(size, N+1)`` matrix from named values with ``matrix``; no caller keeps slices by hand.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import casadi as ca
import numpy as np


class StageParams:
    """Layout of the per-stage parameter vector (column ``k`` of ``P`` belongs to stage ``k``).

    ``internal`` names fields the controller fills itself (e.g. the previous input of the lagged
    input-rate formulation); ``matrix`` leaves them zero instead of requiring a value.
    """

    def __init__(self, fields: Iterable[tuple[str, int]], internal: Iterable[str] = ()):
        self._slices: dict[str, slice] = {}
        offset = 0
        for name, size in fields:
            if name in self._slices:
                raise ValueError(f"stage parameter {name!r} is declared twice")
            if size < 1:
                raise ValueError(f"stage parameter {name!r} must have size >= 1, got {size}")
            self._slices[name] = slice(offset, offset + size)
            offset += size
        self.size = offset
        self.internal = frozenset(internal)
        unknown = self.internal - set(self._slices)
        if unknown:
            raise ValueError(f"internal stage parameters {sorted(unknown)} are not declared")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self._slices)

    def __contains__(self, name: str) -> bool:
        return name in self._slices

    def __getitem__(self, name: str) -> slice:
        try:
            return self._slices[name]
        except KeyError:
            raise KeyError(f"no stage parameter {name!r}; declared: {', '.join(self._slices)}") from None

    def width(self, name: str) -> int:
        s = self[name]
        return s.stop - s.start

    def unpack(self, p) -> dict[str, Any]:
        """Named views of one stage's vector ``p`` (CasADi symbol or numpy array)."""
        return {name: p[s] for name, s in self._slices.items()}

    def symbol(self, name: str = "p") -> ca.SX:
        return ca.SX.sym(name, self.size)

    def matrix(self, n_cols: int, values: Mapping[str, Any]) -> np.ndarray:
        """The ``(size, n_cols)`` parameter matrix from named values.

        Each value is a scalar (every entry, every stage), a vector of the field's width (every
        stage) or a ``(width, n_cols)`` matrix (per stage; ``(n_cols,)`` for a scalar field). Every non-internal field must be
        given; an unknown name or a wrong shape raises ``ValueError`` naming the field.
        """
        P = np.zeros((self.size, n_cols))
        for name, value in values.items():
            if name not in self._slices:
                raise ValueError(f"unknown stage parameter {name!r}; declared: {', '.join(self._slices)}")
            P[self[name]] = self._broadcast(name, np.asarray(value, float), n_cols)
        missing = [n for n in self._slices if n not in values and n not in self.internal]
        if missing:
            raise ValueError(f"stage parameters without a value: {', '.join(missing)}")
        return P

    def _broadcast(self, name: str, a: np.ndarray, n_cols: int) -> np.ndarray:
        width = self.width(name)
        if a.ndim == 0:
            return np.full((width, n_cols), float(a))
        if a.shape == (width,):
            return np.repeat(a[:, None], n_cols, axis=1)
        if a.shape == (width, n_cols):
            return a
        if width == 1 and a.shape == (n_cols,):  # a scalar field, per stage
            return a[None, :]
        raise ValueError(f"stage parameter {name!r}: expected a scalar, shape ({width},) or ({width}, {n_cols}), "
                         f"got shape {a.shape}")
