"""A script's output files, written whole or not at all (atomic.write_beside) onto the file a
path names, and the temporary names they are written under."""
from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from tracker.outputs.atomic import write_beside
from tracker.outputs.files import PARTIAL_SUFFIX, OutputWriteError, partial_path


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
