"""The cache folder (compiled libraries, capacity bounds, kernel checks) and its per-entry locks.

The folder is ``$AERORELAY_CACHE`` or ``~/.cache/aerorelay`` (a private temporary folder, with a
warning, when that is not writable). Entries are published with a checksum and verified before
use (``entry_is_intact``): a truncated or corrupt entry is rebuilt, never loaded.
"""

from __future__ import annotations

import fcntl
import functools
import hashlib
import logging
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

log = logging.getLogger(__name__)


@functools.cache
def _usable(folder: Path) -> Path:
    """``folder`` if it can be created and written; else a private temporary cache, with a warning."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        if os.access(folder, os.W_OK | os.X_OK):
            return folder
    except OSError:
        pass
    fallback = Path(tempfile.gettempdir()) / f"aerorelay-cache-{os.getuid()}"
    fallback.mkdir(parents=True, exist_ok=True)
    log.warning("cache folder %s is not writable: using %s (compiled code and bounds are rebuilt there)", folder, fallback)
    return fallback


def cache_dir() -> Path:
    """``$AERORELAY_CACHE`` or ``~/.cache/aerorelay``; a temporary one when that is not writable."""
    return _usable(Path(os.environ.get("AERORELAY_CACHE", Path.home() / ".cache" / "aerorelay")))


def file_digest(path: Path) -> str:
    """SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def publish_checked(tmp: Path, entry: Path) -> None:
    """Move a finished ``tmp`` file to the cache ``entry`` with its checksum beside it (``.sha256``)."""
    digest = file_digest(tmp)
    os.replace(tmp, entry)
    side = entry.with_name(entry.name + ".sha256")
    side_tmp = side.with_name(f".{side.name}.{os.getpid()}")
    side_tmp.write_text(digest)
    os.replace(side_tmp, side)


def entry_is_intact(entry: Path) -> bool:
    """Whether a cache entry exists and matches the checksum published with it (a truncated or
    altered file, or one without its checksum, is not used: the caller rebuilds it)."""
    side = entry.with_name(entry.name + ".sha256")
    try:
        return entry.is_file() and side.read_bytes().decode("ascii").strip() == file_digest(entry)
    except (OSError, UnicodeDecodeError):  # a sidecar of random bytes is an altered entry as any other
        return False


@contextmanager
def cache_lock(path: Path) -> Iterator[None]:
    """Exclusive lock on ``path``'s cache entry (a ``.lock`` file beside it): processes that would
    build the same entry (dask workers starting together) wait for the first instead."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.parent / f".{path.name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        yield
