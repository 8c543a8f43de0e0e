"""Users' planners from outside the package: a module that registers them (``register_planner`` /
``register_network_planner`` at import), named on the command line (``aerorelay --plugin my_planners run ...``, a
module name or a ``.py`` file) or installed as an entry point of the group ``aerorelay.planners`` (loaded the first
time a scenario names a planner that is not registered). A campaign's workers import the same plugins before their
first run (``experiments.campaign``), so a study flies a user's planner on any dask cluster.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path

ENTRY_POINT_GROUP = "aerorelay.planners"


class PluginError(ValueError):
    """A plugin that cannot be found or imported, named."""


@dataclass(frozen=True)
class Plugin:
    """A planner module: its import name and the folder it is imported from (None: already on the path)."""

    module: str
    folder: str | None = None


def resolve(name: str, here: Path | None = None) -> Plugin:
    """``name``: a module (``my_planners``, ``pkg.planners``) found from ``here`` (default: the working folder) or on the
    path, or a ``.py`` file; a PluginError naming it otherwise (nothing imported yet)."""
    here = Path.cwd() if here is None else Path(here)
    if name.endswith(".py"):
        path = Path(name) if Path(name).is_absolute() else here / name
        if not path.is_file():
            raise PluginError(f"--plugin {name}: no such file")
        return Plugin(path.stem, str(path.resolve().parent))
    top = name.split(".")[0]
    if not all(p.isidentifier() for p in name.split(".")):
        raise PluginError(f"--plugin {name!r}: a module name (my_planners, pkg.planners) or a .py file")
    if (here / f"{top}.py").is_file() or (here / top / "__init__.py").is_file():
        return Plugin(name, str(here.resolve()))
    if importlib.util.find_spec(top) is None:
        raise PluginError(f"--plugin {name}: no module {top!r} in {here} or on Python's path")
    return Plugin(name)


def load(plugins: tuple[Plugin, ...] | list[Plugin]) -> None:
    """Import every plugin (its folder first on the path); an import that fails is a PluginError naming the plugin,
    its own error kept as the cause."""
    for p in plugins:
        if p.folder is not None and p.folder not in sys.path:
            sys.path.insert(0, p.folder)
        try:
            importlib.import_module(p.module)
        except Exception as exc:  # the user's module: whatever it raised, named
            raise PluginError(f"--plugin {p.module}: importing it raised {type(exc).__name__}: {exc}") from exc


_ENTRY_POINTS_LOADED = False


def load_entry_points() -> list[str]:
    """Import every installed entry point of ``aerorelay.planners`` once per process; their names."""
    global _ENTRY_POINTS_LOADED
    if _ENTRY_POINTS_LOADED:
        return []
    _ENTRY_POINTS_LOADED = True
    names = []
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            ep.load()
        except Exception as exc:  # an installed package's: named
            raise PluginError(f"entry point {ep.name} ({ep.value}) of {ENTRY_POINT_GROUP}: importing it raised "
                              f"{type(exc).__name__}: {exc}") from exc
        names.append(ep.name)
    return names
