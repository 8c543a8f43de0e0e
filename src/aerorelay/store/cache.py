"""The cache folder (compiled libraries, capacity bounds, kernel checks) and its per-entry locks.

The folder is ``$AERORELAY_CACHE`` or ``~/.cache/aerorelay``.
"""

from __future__ import annotations

import fcntl
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def cache_dir() -> Path:
    return Path(os.environ.get("AERORELAY_CACHE", Path.home() / ".cache" / "aerorelay"))


@contextmanager
def cache_lock(path: Path) -> Iterator[None]:
    """Exclusive lock on ``path``'s cache entry (a ``.lock`` file beside it): processes that would
    build the same entry (dask workers starting together) wait for the first instead."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.parent / f".{path.name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        yield
