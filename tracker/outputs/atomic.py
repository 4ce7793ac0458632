"""Files written whole or not at all (BVH files; scripts' through whole_files.write_whole), and
the lock of a set of them; the rules of tracker.outputs.files (partial names, aside.set_aside)."""
from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
from pathlib import Path

from tracker.outputs.files import (OutputWriteError, holds_data, open_locked, partial_path,
                                   sync_folder)


def write_beside(path: str | Path, write: Callable[[Path], None],
                 partial: str | Path | None = None) -> None:
    """Call ``write(partial path)``, flush that file to disk and rename it onto ``path`` (a
    symlink there is replaced, not followed: BVH files are named by the sink, not the user);
    on failure the partial file is removed and ``path`` is left as it was (OutputWriteError
    naming the file). partial: the temporary name (default partial_path(path)), in path's
    folder; a non-empty file there is kept aside first (set_aside)."""
    path = Path(path)
    partial = partial_path(path) if partial is None else Path(partial)
    if holds_data(partial):                 # an earlier run's unfinished file
        from tracker.outputs.aside import set_aside
        set_aside(partial)
    try:
        write(partial)
        fd = os.open(partial, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(partial, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(partial)
        if isinstance(exc, OSError):
            raise OutputWriteError(f"{path}: {exc.strerror or exc}", path) from None
        raise
    sync_folder(path.parent)


class LockFile:
    """An exclusive lock held on ``path`` (created, removed by release()) while a set of
    outputs is written; OutputBusyError at once if another process holds it."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        try:
            self._fd = open_locked(self.path, os.O_RDWR)
        except OSError as exc:
            raise OutputWriteError(f"{self.path}: cannot create ({exc.strerror})",
                                   self.path) from None

    def release(self) -> None:
        """Remove the lock file and release the lock; idempotent."""
        if self._fd < 0:
            return
        with contextlib.suppress(OSError):
            os.unlink(self.path)
        fd, self._fd = self._fd, -1
        os.close(fd)
