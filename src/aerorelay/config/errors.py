"""Validation errors as one line per problem, naming the field, its allowed range, and the field
meant when a name is misspelt."""

from __future__ import annotations

import difflib
import re

from pydantic import BaseModel, ValidationError

_BOUND_ERRORS = {"greater_than", "greater_than_equal", "less_than", "less_than_equal"}


def _submodel(ann) -> type[BaseModel] | None:
    """The pydantic model inside an annotation (``X``, ``X | None``, ``list[X]``, ``list[X] | None``)."""
    if isinstance(ann, type) and issubclass(ann, BaseModel):
        return ann
    for arg in getattr(ann, "__args__", ()):
        found = _submodel(arg)
        if found is not None:
            return found
    return None


def _allowed_range(loc: tuple, root: type[BaseModel]) -> str:
    """Human-readable allowed range of the numeric field at ``loc`` (e.g. ``[0, 1]``, ``(0, inf)``)."""
    model: type[BaseModel] | None = root
    info = None
    for part in loc:
        if isinstance(part, int):  # an index into a list of tables
            continue
        if not isinstance(part, str) or model is None or part not in model.model_fields:
            return ""
        info = model.model_fields[part]
        model = _submodel(info.annotation)
    lo, hi, lo_open, hi_open = "-inf", "inf", True, True
    for m in info.metadata if info else []:
        for attr, is_lo, is_open in (("gt", 1, 1), ("ge", 1, 0), ("lt", 0, 1), ("le", 0, 0)):
            v = getattr(m, attr, None)
            if v is not None:
                if is_lo:
                    lo, lo_open = f"{v:g}", bool(is_open)
                else:
                    hi, hi_open = f"{v:g}", bool(is_open)
    return f"{'(' if lo_open else '['}{lo}, {hi}{')' if hi_open else ']'}"


def is_field(loc: tuple, root: type[BaseModel]) -> bool:
    """Whether ``loc`` (field names, list indices as ints) names a field of ``root``'s schema (a table or a value)."""
    model: type[BaseModel] | None = root
    for part in loc:
        if isinstance(part, int):
            continue
        if model is None or part not in model.model_fields:
            return False
        model = _submodel(model.model_fields[part].annotation)
    return True


def did_you_mean(loc: tuple, root: type[BaseModel]) -> str:
    """'; did you mean X?' for the first unknown part of ``loc`` (as ``is_field``'s) close to a field of its table."""
    model: type[BaseModel] | None = root
    for i, part in enumerate(loc):
        if isinstance(part, int):
            continue
        if model is None:
            return ""
        if part not in model.model_fields:
            close = difflib.get_close_matches(str(part), list(model.model_fields), n=1, cutoff=0.6)
            return f"; did you mean {'.'.join(map(str, (*loc[:i], close[0])))!r}?" if close else ""
        model = _submodel(model.model_fields[part].annotation)
    return ""


def _did_you_mean(loc: tuple, root: type[BaseModel]) -> str:
    """'; did you mean X?' for an unknown field close to one of its table's fields."""
    model: type[BaseModel] | None = root
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        if model is None or not isinstance(part, str) or part not in model.model_fields:
            return ""
        model = _submodel(model.model_fields[part].annotation)
    if model is None:
        return ""
    close = difflib.get_close_matches(str(loc[-1]), list(model.model_fields), n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


def format_errors(err: ValidationError, root: type[BaseModel]) -> str:
    """One line per problem: ``field.path: message (got value)``, ranges and did-you-mean spelled out."""
    lines = []
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"]) or "scenario"
        msg = e["msg"].removeprefix("Value error, ")
        got = e.get("input")
        shown = "" if isinstance(got, dict) or e["type"] == "missing" else f" (got {_brief(got)})"
        if e["type"] == "extra_forbidden":
            msg, shown = "unknown field" + _did_you_mean(tuple(e["loc"]), root), ""
        elif e["type"] in _BOUND_ERRORS:
            msg = f"must be in {_allowed_range(tuple(e['loc']), root)}"
        elif e["type"] == "finite_number":
            rng = _allowed_range(tuple(e["loc"]), root)
            msg = f"must be a finite number{' in ' + rng if rng else ''}"
        lines.append(error_line(loc, msg) + shown)
    return "\n".join(lines)


SHOWN_CHARS = 80  # a value quoted in an error is cut to this many characters (a name of 300, a table of tables)


def _brief(value) -> str:
    """``repr(value)``, cut to ``SHOWN_CHARS`` with the length said: an error names the field, not the whole input."""
    text = repr(value)
    if len(text) <= SHOWN_CHARS:
        return text
    return f"{text[:SHOWN_CHARS]}... ({len(text)} characters)"


def error_line(loc: str, msg: str) -> str:
    """``loc: msg``; a check of the whole scenario (``loc`` "scenario") whose message names its field
    first is shown under that field."""
    if loc == "scenario" and _FIELD_PREFIX.match(msg):
        loc, msg = msg.split(": ", 1)
    return f"{loc}: {msg}"


_FIELD_PREFIX = re.compile(r"^(jammers?|mission|controller|nodes|world|relays|sources|network|platform)(\[\d+\])?(\.[a-z_]+)*: ")
