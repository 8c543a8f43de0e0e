"""Output folders the program may write, and how it replaces them without losing anyone's files.

Every folder the program creates (a run, a bound, a campaign) carries a marker file
(``.aerorelay``, naming its kind). A folder is only ever replaced or written into when it does
not exist, is empty, or carries the marker (or is a run/campaign folder of an older version:
``metrics.json`` + ``scenario.toml``, or ``manifest.json``). The working directory, the home
folder, the filesystem root and any folder holding ``.git`` are refused outright. All of this is
checked before any work starts (``check_output_folder``), together with write access and free space.
"""

from __future__ import annotations

import fcntl
import os
import shutil
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from ..filecheck import not_a_folder

MARKER = ".aerorelay"
LOCK_SUFFIX = ".lock"  # .NAME.lock beside a run or bound folder: its one writer holds it
TMP_TAG = "tmp"  # temporary siblings are named .NAME.tmp-PID-XXXX: a later writer removes a dead process's
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


def folder_kind(folder: Path) -> str | None:
    """Which of this program's outputs ``folder`` is (``run``, ``bound``, ``campaign``), from its
    marker or an older version's files; None when it is none of them."""
    folder = Path(folder)
    try:
        kind = (folder / MARKER).read_text().strip()
    except OSError:
        kind = ""
    if kind:
        return kind
    return next((k for k in ("campaign", "run", "bound") if is_own_folder(folder, k)), None)


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


def resolve_output(folder: str | Path) -> Path:
    """``folder``, or where it points when it is a symbolic link (the output is written there and
    the link kept, never replaced by a folder)."""
    folder = Path(folder)
    return folder.resolve() if folder.is_symlink() else folder


def _file_above(folder: Path) -> Path | None:
    """The first existing ancestor of ``folder`` that is not a folder (nothing can be created below it)."""
    for parent in Path(os.path.abspath(folder)).parents:
        if parent.exists():
            return None if parent.is_dir() else parent
    return None


def check_own_file(path: str | Path, option: str, own: Callable[[Path], bool], what: str) -> Path:
    """Raise OutputError unless ``path`` can be written by this program: new, or a regular file ``own(path)`` says it
    wrote (``what`` names such a file). A symbolic link, a folder or any other file in the way is refused by name:
    nothing of the user's is replaced (the run folders' rule, for single files)."""
    p = Path(path)
    if p.is_symlink():
        raise OutputError(f"{option} {p}: a symbolic link is in the way (it would write where it points): choose a new "
                          "name (nothing was written)")
    if p.exists() or os.path.lexists(p):
        if not p.is_file():
            raise OutputError(f"{option} {p}: exists and is not a file (nothing was written)")
        try:
            mine = own(p)
        except (OSError, UnicodeDecodeError, ValueError):
            mine = False
        if not mine:
            raise OutputError(f"{option} {p}: exists and is not {what} this program wrote: choose a new name, or remove "
                              "it yourself (nothing was written)")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise OutputError(f"{option} {p}: its folder {parent} does not exist (nothing was written)")
    return p


def check_output_folder(folder: str | Path, kind: str, *, option: str = "--out", need_bytes: int = 0) -> Path:
    """Raise OutputError unless ``folder`` can take this program's ``kind`` of output: not a file,
    not below a file, not a forbidden place, empty or one of its own folders, its parent writable,
    ``need_bytes`` free. A symbolic link is checked (and later written) where it points."""
    loop = not_a_folder(folder)
    if loop is not None and loop.startswith("a symlink"):
        raise OutputError(f"{option} {folder}: {loop} (nothing was written)")
    folder = resolve_output(folder)
    above = _file_above(folder)
    if above is not None:
        raise OutputError(f"{option} {folder}: {above} is a file, so no folder can be made below it (nothing was written)")
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


def umask() -> int:
    """The process's file-creation mask (read without changing it for other threads for long)."""
    with _UMASK_LOCK:
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


_UMASK_LOCK = threading.Lock()


def follow_umask(path: Path, *, folder: bool) -> None:
    """Give ``path`` the permissions a plain ``mkdir`` / ``open`` would (0777 / 0666 less the umask):
    ``tempfile`` makes private (0700 / 0600) folders and files."""
    os.chmod(path, (0o777 if folder else 0o666) & ~umask())


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def clean_stale_siblings(folder: Path) -> list[Path]:
    """Remove what an interrupted writer of ``folder`` (or of a file) left beside it: temporary
    siblings (``.NAME.tmp-PID-*``) and set-aside old versions (``.NAME.old-PID-*``) whose process is gone.
    Only names this program makes are touched; returns what was removed."""
    folder = Path(folder)
    removed: list[Path] = []
    if not folder.parent.is_dir():
        return removed
    for p in folder.parent.glob(f".{folder.name}.*"):
        rest = p.name[len(folder.name) + 2:]
        tag, _, tail = rest.partition("-")
        pid = tail.split("-", 1)[0]
        if tag not in (TMP_TAG, "old") or not pid.isdigit() or int(pid) == os.getpid() or _pid_alive(int(pid)):
            continue
        if p.is_symlink():
            continue
        if p.is_dir():
            shutil.rmtree(p, ignore_errors=True)
        else:
            p.unlink(missing_ok=True)
        removed.append(p)
    return removed


def new_sibling(folder: Path) -> Path:
    """A fresh temporary folder beside ``folder`` (same filesystem, so renames are atomic), with the
    permissions the user's umask gives; a dead writer's leftovers beside ``folder`` are removed first."""
    folder = Path(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    clean_stale_siblings(folder)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.{TMP_TAG}-{os.getpid()}-", dir=folder.parent))
    follow_umask(tmp, folder=True)
    return tmp


class OutputBusyError(OutputError):
    """Another process is writing the same output folder."""


_HELD: dict[Path, int] = {}  # output folders this process holds the writer's lock of -> nesting depth
_HELD_LOCK = threading.Lock()


def lock_path(folder: Path) -> Path:
    """The one-writer lock file of ``folder``: ``.NAME.lock`` beside it (the folder itself is
    replaced when published, so the lock cannot live inside it); it exists only while held."""
    folder = Path(folder)
    return folder.parent / f".{folder.name}{LOCK_SUFFIX}"


def _lock_file(path: Path, wait: bool) -> int:
    """An open, exclusively locked descriptor of ``path``, which is still the file at ``path`` (a
    holder removes it when done: a waiter that locked the removed file tries again)."""
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666 & ~umask())
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
            if os.fstat(fd).st_ino == os.stat(path).st_ino:
                return fd
        except FileNotFoundError:
            pass
        except BaseException:
            os.close(fd)
            raise
        os.close(fd)


@contextmanager
def writing(folder: str | Path, *, wait: bool = False, option: str = "--out") -> Iterator[Path]:
    """Hold the one-writer lock of ``folder`` (a run or bound folder) while the block runs: a second
    process gets OutputBusyError at once, or waits with ``wait``; the same process may nest it.
    Yields the folder written (where a symbolic link points). Nothing is left behind."""
    folder = resolve_output(folder).absolute()
    with _HELD_LOCK:
        nested = folder in _HELD
        if nested:
            _HELD[folder] += 1
    if nested:
        try:
            yield folder
        finally:
            with _HELD_LOCK:
                _HELD[folder] -= 1
        return
    folder.parent.mkdir(parents=True, exist_ok=True)
    path = lock_path(folder)
    try:
        fd = _lock_file(path, wait)
    except BlockingIOError:
        raise OutputBusyError(f"{option} {folder}: another aerorelay process is writing this folder (lock {path.name} "
                              "beside it); wait for it, pass --wait, or give another folder (nothing was written)") from None
    with _HELD_LOCK:
        _HELD[folder] = 1
    try:
        yield folder
    finally:
        with _HELD_LOCK:
            _HELD.pop(folder, None)
        path.unlink(missing_ok=True)  # still held: a waiter then finds it gone and locks a new one
        os.close(fd)


def swap_in(tmp: Path, folder: Path, kind: str) -> None:
    """Publish the finished ``tmp`` as ``folder``: the old one (only if it is the program's own) is
    moved aside, ``tmp`` renamed into place, then the old one removed; ``folder`` is never half-written."""
    folder = Path(folder)
    mark(tmp, kind)
    old = None
    if folder.exists():
        if any(folder.iterdir()) and not is_own_folder(folder, kind):
            raise OutputError(f"{folder}: holds files this program did not write; not replaced (the new output is in {tmp})")
        old = folder.with_name(f".{folder.name}.old-{os.getpid()}-{time.monotonic_ns()}")
        os.replace(folder, old)
    os.replace(tmp, folder)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same folder and a rename: a full
    disk or an interruption leaves the previous file, never a truncated one."""
    path = Path(path)
    clean_stale_siblings(path)  # a killed writer's temporary file
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.{TMP_TAG}-{os.getpid()}-")
    try:
        follow_umask(Path(tmp), folder=False)
        with os.fdopen(fd, "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
