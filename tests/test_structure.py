"""The package's import structure (docs/concepts/architecture.md): no cycle among its modules'
module-level imports, and no import of the package inside a function body outside ``cli.py``
(a hidden import hides an arrow of the data flow)."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"


def _modules() -> dict[str, Path]:
    return {".".join(p.relative_to(SRC).with_suffix("").parts).removesuffix(".__init__"): p
            for p in sorted((SRC / "aerorelay").rglob("*.py"))}


def _targets(node: ast.Import | ast.ImportFrom, package: str, mods: dict[str, Path]) -> list[str]:
    """The modules of the package an import statement names (``from .x import y``: ``pkg.x.y`` when
    that is a module, else ``pkg.x``)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names if a.name in mods]
    base = node.module or ""
    if node.level:
        parts = package.split(".")[: len(package.split(".")) - node.level + 1]
        base = ".".join(parts + ([base] if base else []))
    return [t for t in (f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names) if t in mods]


def _structure() -> tuple[dict[str, set[str]], list[str]]:
    mods = _modules()
    edges: dict[str, set[str]] = {}
    hidden: list[str] = []
    for mod, path in mods.items():
        tree = ast.parse(path.read_text())
        package = mod if path.name == "__init__.py" else mod.rsplit(".", 1)[0]
        imports = [n for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom))]
        edges[mod] = {t for n in imports for t in _targets(n, package, mods) if t != mod}
        if path.name == "cli.py":
            continue
        for fn in ast.walk(tree):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                hidden += [f"{path.relative_to(SRC)}:{n.lineno}" for n in ast.walk(fn)
                           if isinstance(n, (ast.Import, ast.ImportFrom)) and _targets(n, package, mods)]
    return edges, hidden


def _cycles(edges: dict[str, set[str]]) -> list[str]:
    colour: dict[str, int] = {}
    found: list[str] = []

    def visit(u: str, stack: list[str]) -> None:
        colour[u] = 1
        stack.append(u)
        for v in sorted(edges.get(u, ())):
            if colour.get(v) == 1:
                found.append(" -> ".join(stack[stack.index(v):] + [v]))
            elif not colour.get(v):
                visit(v, stack)
        stack.pop()
        colour[u] = 2

    for m in sorted(edges):
        if not colour.get(m):
            visit(m, [])
    return found


def test_no_import_cycle():
    assert _cycles(_structure()[0]) == []


def test_no_package_import_inside_a_function_outside_the_cli():
    assert _structure()[1] == []


def test_the_checks_see_a_cycle_and_a_hidden_import():
    """The checks themselves: a made-up two-module cycle is found, and the real graph has edges."""
    assert _cycles({"a": {"b"}, "b": {"a"}}) == ["a -> b -> a"]
    edges, _ = _structure()
    assert "aerorelay.config" in edges["aerorelay.assembly.parts"] or "aerorelay.config.scenario" in edges["aerorelay.assembly.parts"]


# Every spelling of "one relay or a network?" (issue 78): Shape's branch fields, sole(), has_two_hops / is_network, a
# comparison of a count of relays or sources. The target is 5, each where the physics differs; this is where it stands
# (2026-12-07): the count may only fall. Each hit is listed on failure.
RELAY_COUNT_QUESTIONS_MAX = 16
RELAY_COUNT = r"\bsole\(|shape\.(plans|bound|neighbours|steps_one)\b|len\([^)]*(relay|source)[^)]*\) *(==|!=|>|<)|is_network|has_two_hops"


def test_the_number_of_relays_is_a_dimension_not_a_fork():
    """Issues 60 and 78: the relay-count question in any spelling is counted, and the count may only fall (the target:
    at most five, each where the physics differs). What differs between the paper's one relay and a network is data
    (``config.scenario.Shape``, chosen once in ``Scenario.shape``)."""
    import re

    pattern = re.compile(RELAY_COUNT)
    not_a_question = re.compile(r"def (sole|has_two_hops)\b|\b[PB]\.shape\b")  # the definitions; an array's shape check
    hits = [f"{p.relative_to(SRC)}:{i}: {line.strip()}" for p in (SRC / "aerorelay").rglob("*.py")
            for i, line in enumerate(p.read_text().splitlines(), 1) if pattern.search(line) and not not_a_question.search(line)]
    assert len(hits) <= RELAY_COUNT_QUESTIONS_MAX, "\n".join(hits)
    counted = re.compile(r"len\((self\.)?relay_list\) *\+ *len\((self\.)?source_list\) *(==|!=|>|<)")  # the shape's, once
    shapes = [f"{p.relative_to(SRC)}:{i}" for p in (SRC / "aerorelay").rglob("*.py")
              for i, line in enumerate(p.read_text().splitlines(), 1) if counted.search(line)]
    assert len(shapes) == 1, shapes


def test_the_relay_count_pattern_sees_every_spelling():
    import re

    pattern = re.compile(RELAY_COUNT)
    for line in ("if sole(relays) is None:", "sc.shape.plans == 'network'", "if len(sc.relay_list) == 1:",
                 "len(control.sources) != 1", "if not sc.has_two_hops:", "is_network = True"):
        assert pattern.search(line), line
    assert not pattern.search("for r in sc.relay_list:")


def test_the_relay_state_is_read_by_name():
    """Issue 60, item 5: no part reads a relay's state by literal offsets (``x[0:3]``, ``xs[r][6:9]``, ``x[5]``):
    through ``models.state``'s named slices or ``unpack``."""
    import re

    literal = re.compile(r"\[(0:3|3:6|6:9|9:12|12:|0:12)(\]|,)|\b(x|xs|x1|xa|xx|x0|vals)\[(3|4|5)\]")
    not_a_state = {"state.py",  # the layout itself
                   "trajectory_generator.py",  # its decision vector z = [p1, p2, p0]
                   "relay_grid.py",  # a source's pose [p, axis]
                   "bound.py"}  # a cube's (x, y, z, tilt, azimuth)
    hits = [f"{p.relative_to(SRC)}:{i}: {line.strip()}" for p in (SRC / "aerorelay").rglob("*.py") if p.name not in not_a_state
            for i, line in enumerate(p.read_text().splitlines(), 1) if literal.search(line)]
    assert not hits, hits


# The floors of docs/concepts/architecture.md: a package imports only from floors below its own (or from its own
# package); the top-level modules are floors of their own.
FLOORS = {"_version": 1, "errors": 1, "filecheck": 1, "stats": 1, "naming": 1, "store": 2, "models": 3, "config": 4,
          "estimation": 4, "planning": 5, "control": 6, "flight": 7, "sim": 7, "assembly": 8, "experiments": 9, "report": 10,
          "api": 11, "cli": 12, "aerorelay": 12}


def _package(mod: str) -> str:
    parts = mod.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def _upward_arrows() -> list[str]:
    edges, _ = _structure()
    out = []
    for mod, targets in edges.items():
        a = _package(mod)
        for t in targets:
            b = _package(t)
            if a != b and FLOORS[b] >= FLOORS[a]:
                out.append(f"{mod} ({a}, floor {FLOORS[a]}) -> {t} ({b}, floor {FLOORS[b]})")
    return sorted(out)


def test_every_package_has_a_floor_and_imports_only_go_down():
    """Issue 78: the package-level knot {config, control, flight, planning} of 2026-12-07 had three arrows back up the
    floors (config -> control.terms, control -> flight.frames, control/flight -> config.network.sole); none now."""
    mods = _modules()
    assert {_package(m) for m in mods} <= set(FLOORS), sorted({_package(m) for m in mods} - set(FLOORS))
    assert _upward_arrows() == []


def test_no_cycle_among_packages():
    """The module graph has no cycle (above); neither has the graph of packages (two on one floor, flight and sim,
    could still reach each other)."""
    edges, _ = _structure()
    packages: dict[str, set[str]] = {}
    for mod, targets in edges.items():
        packages.setdefault(_package(mod), set()).update(_package(t) for t in targets if _package(t) != _package(mod))
    assert _cycles(packages) == []


def test_the_architecture_page_shows_these_floors():
    import re

    page = (SRC.parent / "docs" / "concepts" / "architecture.md").read_text()
    shown = {}
    for floor, cell in re.findall(r"^\| (\d+) \| (.+) \|$", page, flags=re.M):
        for name in re.findall(r"`([a-z_]+)`", cell):
            shown[name] = int(floor)
    shown["aerorelay"] = shown.pop("__init__")  # "the package's __init__"
    assert shown == FLOORS
