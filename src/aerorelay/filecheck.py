"""Why a path is not a file aerorelay can read, said before anything reads it (shared by every reader: scenario,
mission and study files, run folders' files): a FIFO may never end, a device never does, a symlink loop and a
folder are not files."""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path


def not_a_file(path: str | Path) -> str | None:
    """Why ``path`` is not a regular file that can be read (None: it is one): no such file, a symlink loop, a
    folder, a FIFO, a device or a socket, not readable."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return "no such file" + (" (a symlink to nothing)" if os.path.islink(path) else "")
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            return "a symlink loop, not a file"
        return f"cannot be read ({exc.strerror})"
    if stat.S_ISDIR(st.st_mode):
        return "a folder, not a file"
    if stat.S_ISFIFO(st.st_mode):
        return "a FIFO (a named pipe), not a regular file: it may never end"
    if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode):
        return "a device, not a regular file"
    if stat.S_ISSOCK(st.st_mode):
        return "a socket, not a regular file"
    if not os.access(path, os.R_OK):
        return "not readable (permissions)"
    return None


def not_a_folder(path: str | Path) -> str | None:
    """Why ``path`` cannot be used as a folder (None: it is one, or nothing is there yet): a symlink loop, a file."""
    try:
        st = os.stat(path)
    except FileNotFoundError:  # nothing there yet (a link to nothing yet: written where it points)
        return None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            return "a symlink loop, not a folder"
        return f"cannot be used ({exc.strerror})"
    return None if stat.S_ISDIR(st.st_mode) else "not a folder"
