"""Output files that never destroy data: distinct paths, one writer at a time, replace when done.

- :func:`check_distinct` refuses, before anything is written, an output that is (after symlinks,
  relative paths and hard links) the input or another output.
- :class:`OutputFile` writes ``NAME.partial`` beside ``NAME`` (a shorter name when that one
  would be too long: :func:`beside_name`) under an exclusive lock (a second
  run on the same output fails at once with :class:`OutputBusyError`) and renames it onto
  ``NAME`` only by :meth:`OutputFile.commit`, once it is complete. A crash leaves ``NAME`` as it
  was and the new data in ``NAME.partial``. A destination that exists and is not a regular file
  (``/dev/null``, a FIFO), or is a stream the shell opened (``/dev/stdout``, ``/dev/fd/N``:
  :func:`stream_descriptor`), is written in place; a symlink is followed (the target replaced,
  the link kept). A ``NAME.partial`` that already holds data (an earlier run's unfinished
  recording, or a file of the user's) is kept as ``NAME.partial.1`` (``.2``, ...) with a
  warning (:func:`set_aside`), never overwritten.
- :func:`write_beside` does the same for a file written in one go by a function of a path.
- :class:`LockFile` holds such a lock on a lock file of its own (a BVH folder's set of files).
- Every failure to write is an :class:`OutputWriteError` naming the file.
"""
from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import re
import sys
import warnings
from collections.abc import Callable, Iterable
from pathlib import Path

from regressor.errors import SilhouettePoseError

PARTIAL_SUFFIX = ".partial"
#: The longest file name, in bytes, of the usual file systems (ext4, XFS, btrfs, tmpfs).
NAME_MAX = 255


class OutputPathError(SilhouettePoseError, ValueError):
    """An output path that would overwrite the input or another output; one line."""


class _FileError(SilhouettePoseError, RuntimeError):
    """One line starting with the file's path, which is also the ``path`` attribute (None
    when not given): a command can name the option the file came from."""

    def __init__(self, message: str, path: str | Path | None = None):
        super().__init__(message)
        self.path = None if path is None else Path(path)


class OutputBusyError(_FileError):
    """Another process is writing the same output; one line naming the file."""


class OutputWriteError(_FileError):
    """Writing an output failed (disk full, I/O error); one line naming the file."""


_FD_LINK = re.compile(r"/(?:proc/self|dev)/fd/(\d+)")
_STANDARD = {"/dev/stdin": 0, "/dev/stdout": 1, "/dev/stderr": 2}


def stream_descriptor(path: str | Path) -> int | None:
    """N when ``path`` is, or leads by symlinks to, /dev/stdout, /dev/stderr, /dev/fd/N or
    /proc/self/fd/N: a stream the shell opened (a pipe, a terminal, a file with > or >>),
    written through that descriptor so that its offset and append mode are kept; else None."""
    current = os.path.abspath(path)
    for _ in range(40):                  # the kernel's own limit on a chain of links
        if current in _STANDARD:
            return _STANDARD[current]
        match = _FD_LINK.fullmatch(current)
        if match:
            return int(match.group(1))
        try:
            link = os.readlink(current)
        except OSError:
            return None
        current = os.path.normpath(os.path.join(os.path.dirname(current), link))
    return None


def beside_name(path: str | Path, suffix: str) -> Path:
    """``path`` with ``suffix`` added to its name, in the same folder (``NAME.partial``,
    ``.PREFIX.bvh.lock``). Where that name would pass NAME_MAX bytes (a legal 250-byte NAME),
    NAME is cut and ``~`` and 12 hex digits of its SHA-256 follow it, so that every NAME
    still has its own: the same NAME always gives the same name (a second run finds the
    first's lock and partial file)."""
    path = Path(path)
    name = path.name + suffix
    if len(os.fsencode(name)) <= NAME_MAX:
        return path.with_name(name)
    digest = hashlib.sha256(os.fsencode(path.name)).hexdigest()[:12]
    keep = NAME_MAX - len(os.fsencode(suffix)) - len(digest) - 1
    head = os.fsencode(path.name)[:keep].decode(sys.getfilesystemencoding(), "ignore")
    return path.with_name(f"{head}~{digest}{suffix}")


def partial_path(path: str | Path) -> Path:
    """Where ``path`` is written until it is complete: ``NAME.partial`` beside it
    (:func:`beside_name`: a shorter name when that one would be too long)."""
    return beside_name(path, PARTIAL_SUFFIX)


def _identity(path: Path) -> tuple:
    """What makes two paths the same file: (device, inode) of an existing file, else the
    absolute path with symlinks resolved."""
    try:
        status = os.stat(path)
        return ("inode", status.st_dev, status.st_ino)
    except OSError:
        return ("path", os.path.realpath(path))


def check_distinct(named: Iterable[tuple[str, Path]]) -> None:
    """Refuse two of ``named`` (description, path) that are the same file.

    The first entries are the inputs (e.g. ("the input video", path)); an output's description
    says which option it came from (e.g. "--out"). OutputPathError says which two collide.
    """
    seen: dict[tuple, tuple[str, Path]] = {}
    for what, path in named:
        key = _identity(Path(path))
        if key in seen:
            other, other_path = seen[key]
            raise OutputPathError(f"{what} {path} is the same file as {other} {other_path}; "
                                  f"choose another file name (nothing was written)")
        seen[key] = (what, Path(path))


def _open_locked(path: Path, flags: int) -> int:
    """Open (creating) ``path`` and take an exclusive lock on it without waiting; returns the
    descriptor. OutputBusyError if another process holds the lock."""
    for _ in range(10):
        fd = os.open(path, flags | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise OutputBusyError(f"{path}: another track run is writing this output; wait for "
                                  f"it to finish or choose another file name", path) from None
        except BaseException:
            os.close(fd)
            raise
        # The lock holder may have renamed or removed the file between our open and our lock:
        # then we locked a file nobody will look at, so start again on the current one.
        with contextlib.suppress(FileNotFoundError):
            if os.stat(path).st_ino == os.fstat(fd).st_ino:
                return fd
        os.close(fd)
    raise OutputBusyError(f"{path}: kept changing while being locked; another track run is "
                          f"writing this output", path)


def set_aside(path: Path) -> Path | None:
    """Move a non-empty regular file at ``path`` (a ``NAME.partial`` about to be written) to the
    first free ``NAME.partial.N`` and warn naming both; returns the new name, or None when there
    was nothing to keep. OutputBusyError if another process is writing it (holds its lock);
    OutputWriteError if it holds data but cannot be opened to be locked."""
    for _ in range(10):
        try:
            if not path.is_file() or path.stat().st_size == 0:
                return None
        except OSError:
            return None
        fd = _open_to_lock(path)
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise OutputBusyError(f"{path}: another track run is writing this output; wait "
                                      f"for it to finish or choose another file name",
                                      path) from None
            # Moved by another run between our open and our lock (it set it aside and may now
            # write a new one under the name): what we locked is not what the name holds.
            try:
                same = os.stat(path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                return _link_aside(path)
        finally:
            os.close(fd)            # also releases the lock
    raise OutputBusyError(f"{path}: kept changing while being locked; another track run is "
                          f"writing this output", path)


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
    """set_aside's move of the locked ``path`` to the first free ``NAME.N``."""
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
        warnings.warn(f"{path} held an earlier run's unfinished output; kept as {aside}, "
                      f"not overwritten", stacklevel=4)
        return aside
    raise OutputWriteError(f"{path}: too many earlier unfinished outputs kept beside it; "
                           f"remove some", path)


class OutputFile:
    """A binary output written beside ``path`` and renamed onto it by commit() (see the module
    docstring). File protocol for writers: write(bytes) (everything handed to the operating
    system at once, so finished records survive a kill), tell(), flush(), close() (= commit()).
    Attributes: path (destination), written_path (where the bytes go now), committed.
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        stream = stream_descriptor(self.path)
        self._in_place = stream is not None or (self.path.exists() and not self.path.is_file())
        # A symlink the user named is followed: its target is replaced, the link kept.
        self._target = self.path if self._in_place else Path(os.path.realpath(self.path))
        self.written_path = self.path if self._in_place else partial_path(self._target)
        try:
            if stream is not None:
                self._fd = os.dup(stream)
            elif self._in_place:
                self._fd = os.open(self.path, os.O_WRONLY)
            else:
                set_aside(self.written_path)
                self._fd = _open_locked(self.written_path, os.O_WRONLY)
                os.ftruncate(self._fd, 0)   # set_aside kept any data it held
        except OSError as exc:
            raise OutputWriteError(f"{self.written_path}: cannot write ({exc.strerror})",
                                   self.written_path) from None
        self._offset = 0
        self.committed = False

    @property
    def in_place(self) -> bool:
        """True when the bytes go straight to the destination (standard output, a pipe, a
        device): nothing written there can be taken back."""
        return self._in_place

    @property
    def closed(self) -> bool:
        """True once committed or discarded."""
        return self._fd < 0

    def write(self, data) -> int:
        """Write all of ``data``; OutputWriteError naming the file on failure."""
        view = memoryview(data).cast("B")
        done = 0
        try:
            while done < len(view):
                done += os.write(self._fd, view[done:])
        except OSError as exc:
            raise OutputWriteError(f"{self.path}: {exc.strerror or exc}", self.path) from None
        self._offset += done
        return done

    def tell(self) -> int:
        """Bytes written so far."""
        return self._offset

    def flush(self) -> None:
        """Nothing is buffered here: write() hands every byte to the operating system."""

    def commit(self) -> None:
        """Flush to disk and rename onto the destination (replacing it); idempotent."""
        if self.closed:
            return
        try:
            if not self._in_place:
                os.fsync(self._fd)
                os.replace(self.written_path, self._target)
                _sync_folder(self._target.parent)
        except OSError as exc:
            self.discard(keep=True)
            raise OutputWriteError(f"{self.path}: could not be finished ({exc.strerror}); the "
                                   f"data written is in {self.written_path}", self.path) from None
        self._release()
        self.committed = True

    close = commit

    def discard(self, keep: bool = False) -> None:
        """Stop without touching the destination; remove the partial file unless ``keep``."""
        if self.closed:
            return
        self._release()
        if not keep and not self._in_place:
            with contextlib.suppress(OSError):
                os.unlink(self.written_path)

    def _release(self) -> None:
        fd, self._fd = self._fd, -1
        os.close(fd)   # also releases the lock


def _sync_folder(folder: Path) -> None:
    """Make a rename in ``folder`` durable (best effort: not every file system allows it)."""
    with contextlib.suppress(OSError):
        fd = os.open(folder if str(folder) else ".", os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


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
    _sync_folder(path.parent)


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
    partial = (target.with_name(f"{target.stem}{PARTIAL_SUFFIX}{target.suffix}")
               if keep_suffix else None)
    write_beside(target, write, partial)


def file_identity(path: str | Path) -> tuple:
    """What makes two paths the same file (check_distinct): (device, inode) of an existing
    file, else the absolute path with symlinks resolved."""
    return _identity(Path(path))


class LockFile:
    """An exclusive lock held on ``path`` (created, removed by release()) while a set of
    outputs is written; OutputBusyError at once if another process holds it."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        try:
            self._fd = _open_locked(self.path, os.O_RDWR)
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
