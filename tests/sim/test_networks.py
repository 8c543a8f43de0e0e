"""The networks a flight may fly, known before it starts (``sim/networks.py``): a chain whose two relays may
fly home and a spare that may take either's place, written out by hand."""

import numpy as np

from aerorelay.models.antenna import DipolePattern
from aerorelay.models.radio import Antenna, LinkBudget, Node, RadioScene
from aerorelay.sim.networks import every_link, possible_networks

DIPOLE = Antenna(DipolePattern())


def _chain():
    nodes = (Node("bs", "base_station", DIPOLE, np.zeros(3)), Node("s", "source", DIPOLE), Node("r1", "relay", DIPOLE),
             Node("r2", "relay", DIPOLE))
    return RadioScene(nodes, (), LinkBudget(), ("s", "r1", "r2", "bs"))


def test_every_network_of_a_chain_with_relays_going_home_and_a_spare():
    scene, spare = _chain(), Node("sp", "relay", DIPOLE)
    nets = possible_networks(scene, [frozenset()], ["r1", "r2", "sp"], {"sp": spare})
    routes = [n.all_routes[0] for n in nets]
    assert len(routes) == len(set(routes))  # each once
    assert set(routes) == {("s", "r2", "bs"), ("s", "sp", "r2", "bs"), ("s", "r1", "bs"), ("s", "r1", "sp", "bs"),
                           ("s", "bs"), ("s", "sp", "bs")}
    for net in nets:  # a spare in a network is its node; a relay gone is not
        assert {n.name for n in net.nodes if n.role == "relay"} == set(net.all_routes[0][1:-1])
    links = every_link(scene, nets)
    assert set(links.hops) >= {("s", "sp"), ("sp", "r2"), ("r1", "sp"), ("sp", "bs"), ("s", "bs"), ("s", "r1")}
    assert links.hops[: len(scene.hops)] == scene.hops  # the scene's own links first


def test_a_scheduled_loss_and_no_spare_are_the_networks_without_the_lost():
    scene = _chain()
    nets = possible_networks(scene, [frozenset(), frozenset({"r2"})], [], {})
    assert [n.all_routes for n in nets] == [(("s", "r1", "bs"),)]
    assert every_link(scene, []) is scene
