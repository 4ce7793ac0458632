"""Output files written in one go, whole or not at all (BVH files, scripts' outputs), and the
lock of a set of them; the rules of tracker.outputs.files (partial names, aside.set_aside)."""
from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
from pathlib import Path

from tracker.outputs.aside import set_aside
from tracker.outputs.files import (PARTIAL_SUFFIX, OutputWriteError, open_locked, partial_path,
                                   sync_folder)


def write_beside(path: str | Path, write: Callable[[Path], None],
                 partial: str | Path | None = None) -> None:
    """Call ``write(partial path)``, flush that file to disk and rename it onto ``path`` (a
    symlink there is replaced, not followed: BVH files are named by the sink, not the user);
    on failure the partial file is removed and ``path`` is left as it was (OutputWriteError
    naming the file). partial: the temporary name (default partial_path(path)), in path's
    folder; a non-empty file there is kept aside first (set_aside)."""
    shown = path = Path(path)
    partial = partial_path(path) if partial is None else Path(partial)
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
            raise OutputWriteError(f"{shown}: {exc.strerror or exc}", shown) from None
        raise
    sync_folder(path.parent)


def write_whole(path: str | Path, write: Callable[[Path], None],
                keep_suffix: bool = False) -> None:
    """A script's output file written whole or not at all: write_beside onto the file the
    path names, a symlink followed (its target replaced, the link kept); a path that exists
    and is not a regular file (/dev/null, /dev/stdout, a FIFO) is written in place. With
    keep_suffix the temporary name ends in path's suffix (NAME.partial.png: OpenCV picks an
    image's format by it). OutputWriteError naming the file on failure."""
    given = Path(path)
    # Checked on the path as given (exists and is_file follow links): a pipe has no path that
    # realpath could give.
    if given.exists() and not given.is_file():
        try:
            write(given)
        except OSError as exc:
            raise OutputWriteError(f"{path}: {exc.strerror or exc}", path) from None
        return
    target = Path(os.path.realpath(path))
    write_beside(target, write, temporary_names(target)[1] if keep_suffix else None)


def temporary_names(path: str | Path) -> tuple[Path, Path]:
    """The two names write_whole may write the file ``path`` names (a symlink followed) under
    until it is complete: ``NAME.partial`` and, with keep_suffix, ``STEM.partial.SUFFIX``. A
    script refuses an output whose temporary name is one of its inputs (it would be set aside)."""
    target = Path(os.path.realpath(path))
    return partial_path(target), target.with_name(f"{target.stem}{PARTIAL_SUFFIX}{target.suffix}")


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
