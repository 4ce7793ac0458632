"""Keeping an earlier run's unfinished output aside before its name is written again
(:func:`set_aside`), so that no data is overwritten unseen."""
from __future__ import annotations

import fcntl
import os
import warnings
from pathlib import Path

from tracker.outputs.failures import busy_error
from tracker.outputs.files import OutputWriteError, beside_name, holds_data, same_file


def set_aside(path: Path) -> Path | None:
    """Keep a non-empty file at ``path`` (a ``NAME.partial`` about to be written) as the first
    free ``NAME.partial.N`` (keep_aside); the new name, or None when there was none."""
    return keep_aside(path) if holds_data(path) else None


def keep_aside(path: Path) -> Path | None:
    """Move the file at ``path`` to the first free ``NAME.N`` and warn naming both; returns
    the new name, or None when it no longer holds data. OutputBusyError if another process
    is writing it (holds its lock); OutputWriteError if it cannot be opened to be locked."""
    for attempt in range(10):
        if attempt and not holds_data(path):
            return None
        fd = _open_to_lock(path)
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise busy_error(path) from None
            if same_file(path, fd):    # else another run set it aside and may write anew
                return _link_aside(path)
        finally:
            os.close(fd)            # also releases the lock
    raise busy_error(path, changing=True)


def _open_to_lock(path: Path) -> int:
    """A descriptor of ``path`` to flock (read or, failing that, write access suffices);
    OutputWriteError when neither is allowed: its data must not be written over unseen."""
    for flags in (os.O_RDONLY, os.O_WRONLY):
        try:
            return os.open(path, flags)
        except OSError as exc:
            error = exc
    raise OutputWriteError(f"{path}: holds an earlier run's data that cannot be kept aside "
                           f"({error.strerror}); move it away first", path)


def _link_aside(path: Path) -> Path:
    """Move the locked ``path`` to the first free ``NAME.N``."""
    for n in range(1, 10_000):
        aside = beside_name(path, f".{n}")
        try:
            os.link(path, aside)      # never replaces an existing file, unlike rename
        except FileExistsError:
            continue
        except OSError as exc:
            raise OutputWriteError(f"{path}: holds an earlier run's data and cannot be kept "
                                   f"aside ({exc.strerror}); move it away first", path) from None
        os.unlink(path)
        # stacklevel: the warning names the line that opened the output (OutputFile, write_beside)
        warnings.warn(f"{path} held an earlier run's unfinished output; kept as {aside}, "
                      f"not overwritten", stacklevel=5)
        return aside
    raise OutputWriteError(f"{path}: too many earlier unfinished outputs kept beside it; "
                           f"remove some", path)
