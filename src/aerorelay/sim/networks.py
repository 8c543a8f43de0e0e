"""The networks a flight may fly besides the one it starts with, known before it starts: after each
scheduled loss, with relays gone home and spares in their places (``possible_networks``), and the one
scene holding every link of them all (``every_link``): the log's columns and the plant's per-link random
channel terms are laid out from them before the first step."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from itertools import combinations, permutations

from ..models.radio import Node, RadioScene


def every_link(scene: RadioScene, networks: Sequence[RadioScene]) -> RadioScene:
    """``scene`` with every route of ``networks`` (the networks the flight may fly besides ``scene``: after a
    loss, with spares in relays' places): its links are every link the network ever takes, the scene's own
    first (``scene`` itself when no network adds a route)."""
    routes, ends = list(scene.all_routes), list(scene.route_ends)
    skips = list(scene.skips) if scene.skips else [tuple(r[1:-1]) for r in routes]
    nodes = list(scene.nodes)
    for net in networks:
        for i, (r, e) in enumerate(zip(net.all_routes, net.route_ends, strict=True)):
            if r not in routes:
                routes.append(r)
                ends.append(e)
                skips.append(net.skips[i] if net.skips else tuple(r[1:-1]))
        nodes += [n for n in net.nodes if n.name not in {m.name for m in nodes}]
    if len(routes) == len(scene.all_routes):
        return scene
    return replace(scene, nodes=tuple(nodes), routes=tuple(routes), handover=tuple(ends) if any(ends) else (),
                   skips=tuple(skips) if scene.skips else ())


def possible_networks(scene: RadioScene, scheduled: Sequence[frozenset[str]], homing: Sequence[str],
                      spares: Mapping[str, Node]) -> list[RadioScene]:
    """Every network a flight of ``scene`` may fly besides ``scene`` itself: after each ``scheduled`` loss (the
    relays lost by then), with any of the relays that may fly home (``homing``) gone, and each spare (``spares``:
    name -> node) in the place of one of them; each network once, in that order."""
    out: list[RadioScene] = []
    seen = {(scene.all_routes, scene.node_names)}
    for lost in scheduled:
        for k in range(len(homing) + 1):
            for sub in combinations(homing, k):
                for placed in _placements([h for h in sub if h not in spares] + [h for h in sub if h in spares], spares):
                    net = scene
                    for leaving, spare in placed:
                        if leaving in net.node_names and spare not in net.node_names:
                            net = net.handed_to(leaving, spares[spare])
                    net = net.without(lost | set(sub))
                    key = (net.all_routes, net.node_names)
                    if key not in seen:
                        seen.add(key)
                        out.append(net)
    return out


def _placements(leaving: Sequence[str], spares: Mapping[str, Node]) -> list[list[tuple[str, str]]]:
    """Every way to put distinct spares in the places of some of ``leaving`` (none first): ``[(relay, spare)]``."""
    out: list[list[tuple[str, str]]] = [[]]
    for k in range(1, min(len(leaving), len(spares)) + 1):
        for who in combinations(leaving, k):
            out += [list(zip(who, chosen, strict=True)) for chosen in permutations(spares, k) if not set(who) & set(chosen)]
    return out
