"""Output folders the program may write, and how it replaces them without losing anyone's files.

Every folder the program creates (a run, a bound, a campaign) carries a marker file
(``.aerorelay``, naming its kind). A folder is only ever replaced or written into when it does
not exist, is empty, or carries the marker (or is a run/campaign folder of an older version:
``metrics.json`` + ``scenario.toml``, or ``manifest.json``). The working directory, the home
folder, the filesystem root and any folder holding ``.git`` are refused outright. All of this is
checked before any work starts (``check_output_folder``), together with write access and free space.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

MARKER = ".aerorelay"
LEGACY_SIGNATURES = {"run": ("metrics.json", "scenario.toml"), "campaign": ("manifest.json",), "bound": ("bound.json",)}


class OutputError(ValueError):
    """An output folder the program must not (or cannot) write; names the folder and why."""


def is_own_folder(folder: Path, kind: str) -> bool:
    """Whether ``folder`` was written by this program (its marker, or an older version's files)."""
    folder = Path(folder)
    if (folder / MARKER).is_file():
        return True
    sig = LEGACY_SIGNATURES.get(kind, ())
    return bool(sig) and all((folder / f).is_file() for f in sig)


def _forbidden(folder: Path) -> str | None:
    resolved = folder.resolve()
    if resolved == Path.cwd().resolve():
        return "is the working directory"
    if resolved == Path.home().resolve():
        return "is the home folder"
    if resolved == Path(resolved.anchor):
        return "is the filesystem root"
    if (resolved / ".git").exists():
        return "holds a .git repository"
    return None


def check_output_folder(folder: str | Path, kind: str, *, option: str = "--out", need_bytes: int = 0) -> Path:
    """Raise OutputError unless ``folder`` can take this program's ``kind`` of output: not a file,
    not a forbidden place, empty or one of its own folders, its parent writable, ``need_bytes`` free."""
    folder = Path(folder)
    why = _forbidden(folder)
    if why:
        raise OutputError(f"{option} {folder}: {why}; give a new or empty folder (nothing was written)")
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"{option} {folder}: is a file, not a folder (nothing was written)")
    if folder.is_dir() and any(folder.iterdir()) and not is_own_folder(folder, kind):
        raise OutputError(f"{option} {folder}: exists and holds files this program did not write; it replaces only its own "
                          f"{kind} folders (marker {MARKER}); give a new or empty folder (nothing was written)")
    parent = folder.resolve().parent
    while not parent.exists():
        parent = parent.parent
    target = folder if folder.is_dir() else parent
    if not os.access(target, os.W_OK | os.X_OK):
        raise OutputError(f"{option} {folder}: {target} is not writable (nothing was written)")
    if need_bytes:
        free = shutil.disk_usage(target).free
        if free < need_bytes:
            raise OutputError(f"{option} {folder}: {free / 1e6:.0f} MB free on its disk, the output needs about "
                              f"{need_bytes / 1e6:.0f} MB (nothing was written)")
    return folder


def mark(folder: Path, kind: str) -> None:
    """Write the marker that makes ``folder`` one of this program's own ``kind`` folders."""
    (Path(folder) / MARKER).write_text(f"{kind}\n")


def new_sibling(folder: Path) -> Path:
    """A fresh temporary folder beside ``folder`` (same filesystem, so renames are atomic)."""
    folder = Path(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    return Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))


def swap_in(tmp: Path, folder: Path, kind: str) -> None:
    """Publish the finished ``tmp`` as ``folder``: the old one (only if it is the program's own) is
    moved aside, ``tmp`` renamed into place, then the old one removed; ``folder`` is never half-written."""
    folder = Path(folder)
    mark(tmp, kind)
    old = None
    if folder.exists():
        if any(folder.iterdir()) and not is_own_folder(folder, kind):
            raise OutputError(f"{folder}: holds files this program did not write; not replaced (the new output is in {tmp})")
        old = folder.with_name(f".{folder.name}.old-{os.getpid()}")
        os.replace(folder, old)
    os.replace(tmp, folder)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same folder and a rename: a full
    disk or an interruption leaves the previous file, never a truncated one."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
