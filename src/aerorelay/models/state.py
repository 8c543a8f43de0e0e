"""A relay's state by name, one layout for every part (as RotorPy keeps its state behind names):
``x = [p, eta, v, omega, Omega]``: position ``p`` (m, world ENU), attitude ``eta`` (roll, pitch, yaw; rad,
ZYX Euler), velocity ``v`` (m/s, world), body rate ``omega`` (rad/s, body FLU) and the rotor speeds
``Omega`` (Hz, one per rotor). Parts read a state through these slices, or ``unpack`` it, never by
literal offsets; ``pack`` writes one. *Dual*: the slices index numpy arrays and CasADi expressions alike."""

from __future__ import annotations

import numpy as np

P = slice(0, 3)  # position (m, world)
ETA = slice(3, 6)  # roll, pitch, yaw (rad, ZYX)
V = slice(6, 9)  # velocity (m/s, world)
OMEGA = slice(9, 12)  # body rate (rad/s, body)
ROTORS = slice(12, None)  # rotor speeds (Hz)
RIGID = slice(0, 12)  # the rigid body's part: p, eta, v, omega
ROLL, PITCH, YAW = 3, 4, 5  # eta's entries in x
RIGID_NAMES = ("p_x", "p_y", "p_z", "phi", "theta", "psi", "v_x", "v_y", "v_z", "omega_x", "omega_y", "omega_z")  # x[RIGID]


def unpack(x):
    """``(p, eta, v, omega, Omega)`` of a state (views of ``x``, not copies)."""
    return x[P], x[ETA], x[V], x[OMEGA], x[ROTORS]


def pack(p, eta, v, omega, rotors) -> np.ndarray:
    """A state from its parts (a new array)."""
    return np.concatenate([np.asarray(p, float), np.asarray(eta, float), np.asarray(v, float),
                           np.asarray(omega, float), np.asarray(rotors, float)])
