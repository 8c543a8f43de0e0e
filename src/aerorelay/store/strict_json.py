"""Strict JSON for every file the program writes: no ``NaN`` or ``Infinity`` (which ``json.dumps``
emits by default and strict parsers refuse); a value that is not a finite number is written as
``null`` and, in a JSON object at the top, its reason under ``null_reasons`` (key: the value's
dotted path)."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

NULL_REASONS = "null_reasons"


def _clean(obj: Any, path: str, reasons: dict[str, str]) -> Any:
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float):
        if math.isfinite(obj):
            return obj
        reasons.setdefault(path or "value", f"not a finite number ({obj!r})")
        return None
    if isinstance(obj, dict):
        return {k: _clean(v, f"{path}.{k}" if path else str(k), reasons) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v, f"{path}.{i}" if path else str(i), reasons) for i, v in enumerate(obj)]
    if isinstance(obj, np.ndarray):
        return _clean(obj.tolist(), path, reasons)
    return obj


def finite(obj: Any) -> tuple[Any, dict[str, str]]:
    """``obj`` with every non-finite float replaced by None (numpy scalars and arrays as Python
    values), and the reasons by dotted path."""
    reasons: dict[str, str] = {}
    return _clean(obj, "", reasons), reasons


def dumps(obj: Any, **kwargs) -> str:
    """``json.dumps`` that never writes NaN / Infinity: those become null, with their reason under
    ``null_reasons`` when ``obj`` is a dict (reasons already there are kept)."""
    clean, reasons = finite(obj)
    if reasons and isinstance(clean, dict):
        clean[NULL_REASONS] = {**reasons, **(clean.get(NULL_REASONS) or {})}
    return json.dumps(clean, allow_nan=False, **kwargs)
