"""Keeping Python's cyclic garbage collector out of the control loop's step time.

A full (generation-2) collection of the cyclic garbage collector walks every tracked object of the
process: measured on this VM during the 47 s nominal mission, one such collection took 70-100 ms
(184 000 tracked objects) and landed in whichever control step was running: the 84-122 ms maxima
``aerorelay bench`` reported with the jammer estimator on, earlier put down to the VM. Reference
counting frees everything that is not part of a cycle, and the young generations (cheap: < 1 ms
here) still collect the cycles the loop makes (~19 000 objects per mission); only the automatic
full collections wait until the loop is done.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager

_NEVER = 1 << 30  # generation-1 collections before a full one: none during the loop


@contextmanager
def full_collections_paused() -> Iterator[None]:
    """Within the block, the cyclic garbage collector does no automatic full collection; the
    thresholds are restored afterwards (the next full collection then runs outside the loop)."""
    t0, t1, t2 = gc.get_threshold()
    gc.set_threshold(t0, t1, _NEVER)
    try:
        yield
    finally:
        gc.set_threshold(t0, t1, t2)
