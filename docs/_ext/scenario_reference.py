"""The scenario reference, generated from the pydantic schema at every docs build (so it cannot
drift from the code): one table per TOML table, every field with its type, default, unit, allowed
range and description. A field without a description fails the build."""

from __future__ import annotations

import re
import types
import typing
from pathlib import Path

from pydantic import BaseModel
from pydantic_core import PydanticUndefined
from sphinx.errors import ExtensionError

UNIT_SUFFIXES = {  # field-name endings that carry the unit
    "_m": "m", "_s": "s", "_hz": "Hz", "_hz_s": "Hz/s", "_deg": "deg", "_w": "W", "_dbm": "dBm", "_db": "dB", "_kg": "kg",
    "_kgm2": "kg m^2", "_m_s": "m/s", "_m_s2": "m/s^2", "_deg_s": "deg/s", "_rad_s": "rad/s", "_dbi": "dBi",
}
OUT = "reference/scenario.md"


_UNITS = r"(m/s\^2|m/s|rad/s\^2|rad/s|deg/s|Hz/s|Hz|dBm|dBi|dB|deg|W|kg|K|m|s)"


def _unit(name: str, description: str) -> str:
    """From the field's name (``_m``, ``_hz_s``, ...) or its description (``"m, world"``, ``"..., m/s"``)."""
    for suffix in sorted(UNIT_SUFFIXES, key=len, reverse=True):
        if name.endswith(suffix):
            return UNIT_SUFFIXES[suffix]
    m = re.match(_UNITS + r"[,;]", description) or re.search(r", " + _UNITS + r"(?=$|[ ,;)])", description)
    return m.group(1) if m else ""


def _type(ann) -> str:
    origin = typing.get_origin(ann)
    if origin is typing.Annotated:
        return _type(typing.get_args(ann)[0])
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_type(a) for a in typing.get_args(ann))
    if origin is typing.Literal:
        return " / ".join(repr(a) for a in typing.get_args(ann))
    if origin is list:
        (inner,) = typing.get_args(ann) or (typing.Any,)
        return f"list of {_type(inner)}"
    if isinstance(ann, type) and issubclass(ann, BaseModel):
        return "table"
    if ann is type(None):
        return "none"
    return getattr(ann, "__name__", str(ann))


def _range(info) -> str:
    lo = hi = ""
    for m in info.metadata:
        for attr, side in (("gt", "("), ("ge", "["), ("lt", ")"), ("le", "]")):
            v = getattr(m, attr, None)
            if v is not None:
                if side in "([":
                    lo = f"{side}{v:g}"
                else:
                    hi = f"{v:g}{side}"
        if getattr(m, "min_length", None) is not None and getattr(m, "max_length", None) == getattr(m, "min_length", None):
            return f"{m.min_length} items"
    if not lo and not hi:
        return ""
    return f"{lo or '(-inf'}, {hi or 'inf)'}"


def _default(info) -> str:
    if info.default_factory is not None:
        try:
            v = info.default_factory()
        except TypeError:
            return "(computed)"
    elif info.default is PydanticUndefined:
        return "required"
    else:
        v = info.default
    if isinstance(v, BaseModel):
        return "(table)"
    if v is None:
        return "unset"
    return f"`{v!r}`".replace("|", "\\|") if not isinstance(v, list) or len(str(v)) < 60 else "(see the preset)"


def _submodel(ann):
    if isinstance(ann, type) and issubclass(ann, BaseModel):
        return ann
    for arg in typing.get_args(ann):
        found = _submodel(arg)
        if found is not None:
            return found
    return None


def render(model: type[BaseModel] | None = None, head: str | None = None) -> str:
    """The reference of ``model`` (default the scenario's) under ``head`` (default the scenario reference's)."""
    from aerorelay.config import Scenario

    model = model or Scenario
    missing: list[str] = []
    sections: list[str] = []

    walked: dict[type, str] = {}

    def walk(model: type[BaseModel], prefix: str) -> None:
        walked[model] = prefix[:-1]
        rows, subs = [], []
        for name, info in model.model_fields.items():
            key = f"{prefix}{name}"
            sub = _submodel(info.annotation)
            if not info.description and not (sub is not None and (sub.__doc__ or "").strip()):
                missing.append(key)
            desc = " ".join((info.description or "").split()).replace("|", "\\|")
            kind = _type(info.annotation)
            unit = "" if "'" in kind or kind in ("str", "bool", "str or none") else _unit(name, desc)
            if sub is not None and sub is not model:
                first = " ".join((sub.__doc__ or "").strip().split("\n\n")[0].split()).replace("|", "\\|")
                table = walked.get(sub) or key
                if sub not in walked and all(s is not sub for s, _ in subs):
                    subs.append((sub, key))
                desc, unit = f"{desc or first} (table: see `[{table}]`)".strip(), ""
            rows.append(f"| `{name}` | {kind.replace('|', '/')} | {_default(info)} | {unit} | "
                        f"{_range(info)} | {desc} |")
        title = f"`[{prefix[:-1]}]`" if prefix else "top level"
        doc = " ".join((model.__doc__ or "").split())
        sections.append(f"## {title}\n\n{doc}\n\n| field | type | default | unit | allowed | description |\n"
                        "|---|---|---|---|---|---|\n" + "\n".join(rows) + "\n")
        for sub, key in subs:
            walk(sub, key + ".")

    walk(model, "")
    if missing:
        raise ExtensionError(f"{model.__name__} fields without a description ({len(missing)}): {', '.join(missing)}")
    head = head or ("# Scenario reference\n\nGenerated from the schema (`aerorelay.config`) at every docs build. "
            "A scenario file states only what differs from these defaults; `aerorelay validate FILE` prints it "
            "fully resolved. Lists of tables (`[[jammers]]`, `[[platform.rotors]]`) repeat the table's fields per item. "
            "Ranges: `[` / `]` include the bound, `(` / `)` exclude it.\n\n")
    return head + "\n".join(sections)


STUDY_OUT = "reference/study.md"
STUDY_HEAD = ("# Study reference\n\nGenerated from the schema (`aerorelay.experiments.study.Study`) at every docs build: "
              "the fields of a study file (`experiments/*.toml`, `aerorelay reproduce`). A study's `base` and a run "
              "group's own `base` are named relative to the folder above the studies folder (the repository for "
              "`experiments/`); absolute paths are taken as they are. `aerorelay reproduce --list` names the studies "
              "with their run counts. Lists of tables (`[[runs]]`, `[[claims]]`) repeat the table's fields per item.\n\n")


def render_study() -> str:
    from aerorelay.experiments.study import Study

    return render(Study, STUDY_HEAD)


def _write(app) -> None:
    for out, text in ((OUT, render()), (STUDY_OUT, render_study())):
        path = Path(app.srcdir) / out
        if not path.exists() or path.read_text() != text:
            path.write_text(text)


def setup(app):
    app.connect("builder-inited", _write)
    return {"version": "1", "parallel_read_safe": True}
