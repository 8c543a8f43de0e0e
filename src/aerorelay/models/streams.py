"""Independent random streams per purpose, derived from a run's seed.

Each purpose draws from its own ``numpy.random.SeedSequence(seed, spawn_key=(k,))`` (what
``SeedSequence(seed).spawn`` hands out as child ``k``): the streams of one run never share draws,
and neither do the streams of two runs with different seeds (the old ``seed + k`` offsets made run
``s``'s fading the same stream as run ``s + 1``'s CSI noise). A new purpose goes at the end of
``PURPOSES``, so the existing streams keep their numbers.
"""

from __future__ import annotations

import numpy as np

PURPOSES: tuple[str, ...] = (
    "csi",  # the relay's measurement noise on MRAV-2's and the jammers' positions (sim/closed_loop)
    "process",  # the plant's translational and rotational acceleration noise (sim/closed_loop)
    "fading",  # small-scale Rician fading, i.i.d. or Doppler (sim/perturbations, models/fading)
    "shadowing",  # the log-normal shadowing field (models/propagation.ShadowingField)
    "los",  # RMa-AV line-of-sight states, one uniform per link (models/propagation)
    "detector",  # the energy detectors' chi-square readings (models/sensing, sim/jammer_sensing)
    "wind",  # the Dryden gusts (sim/air, models/wind)
)


def stream(seed: int, purpose: str) -> np.random.SeedSequence:
    """The seed sequence of ``purpose`` (one of ``PURPOSES``) for the run seeded ``seed`` (>= 0)."""
    if purpose not in PURPOSES:
        raise ValueError(f"random stream {purpose!r}: not one of {PURPOSES}")
    return np.random.SeedSequence(int(seed), spawn_key=(PURPOSES.index(purpose),))


def generator(seed: int, purpose: str) -> np.random.Generator:
    """A generator on ``stream(seed, purpose)``."""
    return np.random.default_rng(stream(seed, purpose))
