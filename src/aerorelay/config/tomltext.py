"""Compact TOML text: arrays of scalars on one line, tables as sections (round-trips through tomllib)."""

from __future__ import annotations

import math

import tomli_w


def _toml_value(v) -> str:
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, float) and math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return tomli_w.dumps({"v": v})[4:].strip()  # TOML's own scalar syntax (strings, numbers, booleans)


def compact_toml(data: dict, prefix: str = "") -> str:
    """TOML text with every array of scalars (or of arrays) on one line; tables and arrays of
    tables as sections. Round-trips through ``tomllib``."""
    scalars = {k: v for k, v in data.items() if not isinstance(v, dict) and not _is_table_array(v)}
    lines = [f"{k} = {_toml_value(v)}" for k, v in scalars.items()]
    for k, v in data.items():
        name = f"{prefix}{k}"
        if isinstance(v, dict):
            lines += ["", f"[{name}]", compact_toml(v, name + ".").strip("\n")]
        elif _is_table_array(v):
            for item in v:
                lines += ["", f"[[{name}]]", compact_toml(item, name + ".").strip("\n")]
    return "\n".join(lines) + "\n"


def _is_table_array(v) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)
