"""Checks at the Python API's boundary: objects a user builds (jammers, antennas, nodes, scenes,
link budgets, a planner's references) refuse bad values when they are made, with the same kind of
named error a scenario file gets: the object, the field, the allowed range and what was given."""

from __future__ import annotations

import math
from numbers import Real

import numpy as np


class InvalidInput(ValueError):
    """A value an object does not accept; ``str()`` names the object, the field and the allowed range."""


def _range(lo: float, hi: float, lo_open: bool, hi_open: bool) -> str:
    lo_open, hi_open = lo_open or lo == -math.inf, hi_open or hi == math.inf
    return f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"


def number(owner: str, field: str, value, *, lo: float = -math.inf, hi: float = math.inf, lo_open: bool = False,
           hi_open: bool = False) -> float:
    """``value`` as a float if it is a finite real number in the range, else InvalidInput naming
    ``owner.field`` and the range (``lo_open`` / ``hi_open``: the bound itself excluded)."""
    rng = _range(lo, hi, lo_open, hi_open)
    if isinstance(value, bool) or not isinstance(value, Real | np.number):
        raise InvalidInput(f"{owner}.{field}: must be a number in {rng} (got {value!r})")
    v = float(value)
    below = v <= lo if lo_open else v < lo
    above = v >= hi if hi_open else v > hi
    if not math.isfinite(v) or below or above:
        raise InvalidInput(f"{owner}.{field}: must be a finite number in {rng} (got {value!r})")
    return v


def vector(owner: str, field: str, value, n: int = 3, *, nonzero: bool = False, unit: bool = False) -> np.ndarray:
    """``value`` as a float array of ``n`` finite numbers (``nonzero``: not the zero vector; ``unit``:
    of length 1 within 1e-6), else InvalidInput naming ``owner.field``."""
    what = f"{n} finite numbers" + (" of length 1" if unit else ", not all zero" if nonzero else "")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInput(f"{owner}.{field}: must be {what} (got {value!r})") from None
    if isinstance(value, str | bytes) or arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise InvalidInput(f"{owner}.{field}: must be {what} (got {value!r})")
    norm = float(np.linalg.norm(arr))
    if (nonzero or unit) and norm == 0.0 or unit and abs(norm - 1.0) > 1e-6:
        raise InvalidInput(f"{owner}.{field}: must be {what} (got {value!r}, length {norm:g})")
    return arr


def text(owner: str, field: str, value, *, optional: bool = False) -> None:
    """``value`` a non-empty string (or None when ``optional``), else InvalidInput."""
    if value is None and optional:
        return
    if not isinstance(value, str) or not value:
        raise InvalidInput(f"{owner}.{field}: must be a non-empty string{' or None' if optional else ''} (got {value!r})")


def one_of(owner: str, field: str, value, allowed) -> None:
    """``value`` one of ``allowed``, else InvalidInput listing them."""
    if value not in allowed:
        raise InvalidInput(f"{owner}.{field}: must be one of {', '.join(map(repr, allowed))} (got {value!r})")


def has_method(owner: str, field: str, value, method: str, kind: str) -> None:
    """``value`` an object with ``method`` (a ``kind``), else InvalidInput."""
    if not callable(getattr(value, method, None)):
        raise InvalidInput(f"{owner}.{field}: must be {kind} (an object with {method}()), got {type(value).__name__}")
