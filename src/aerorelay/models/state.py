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


PARTS = (("p", P), ("eta", ETA), ("v", V), ("omega", OMEGA), ("Omega", ROTORS))  # the parts by name, in order


def state_vector(state, n_rotors: int, who: str = "state") -> np.ndarray:
    """A relay's state as the flat vector: ``state`` is one already (``12 + n_rotors`` numbers) or a mapping of its
    parts by name (``p``, ``eta``, ``v``, ``omega``: three numbers each; ``Omega``: one per rotor). A ValueError
    naming ``who`` and what is wrong otherwise."""
    nx = 12 + n_rotors
    if isinstance(state, dict) or hasattr(state, "keys"):
        names = [n for n, _ in PARTS]
        unknown, missing = sorted(set(state) - set(names)), [n for n in names if n not in state]
        if unknown or missing:
            raise ValueError(f"{who}: a state by name has the parts {', '.join(names)}"
                             + (f"; missing {', '.join(missing)}" if missing else "")
                             + (f"; unknown {', '.join(map(str, unknown))}" if unknown else ""))
        sizes = {"p": 3, "eta": 3, "v": 3, "omega": 3, "Omega": n_rotors}
        parts = []
        for name in names:
            try:
                a = np.asarray(state[name], float).reshape(-1)
            except (TypeError, ValueError):
                raise ValueError(f"{who}[{name!r}] must be {sizes[name]} numbers, got {state[name]!r}") from None
            if a.shape != (sizes[name],):
                raise ValueError(f"{who}[{name!r}] must be {sizes[name]} numbers, got {a.size}")
            parts.append(a)
        return np.concatenate(parts)
    try:
        x = np.asarray(state, float)
    except (TypeError, ValueError):
        raise ValueError(f"{who} must be {nx} numbers (p, eta, v, omega, Omega) or a mapping of those parts by name, "
                         f"got {type(state).__name__}") from None
    if x.shape != (nx,):
        raise ValueError(f"{who} must be {nx} numbers (p, eta, v, omega, Omega), got shape {x.shape}")
    return x


def unpack(x):
    """``(p, eta, v, omega, Omega)`` of a state (views of ``x``, not copies)."""
    return x[P], x[ETA], x[V], x[OMEGA], x[ROTORS]


def pack(p, eta, v, omega, rotors) -> np.ndarray:
    """A state from its parts (a new array)."""
    return np.concatenate([np.asarray(p, float), np.asarray(eta, float), np.asarray(v, float),
                           np.asarray(omega, float), np.asarray(rotors, float)])
