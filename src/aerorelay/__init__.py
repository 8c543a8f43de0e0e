"""aerorelay: communications-aware control of multirotor aerial relays under jamming.

Implements Silano et al., *Communications-Aware NMPC for Multi-Rotor Aerial Relay Networks
Under Jamming Interference*: a max-min trajectory generator plus a communications-aware NMPC
on a generically-tilted multirotor (GTMR) model.
"""

__version__ = "0.1.0"
