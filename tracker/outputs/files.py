"""Output files that never destroy data: :class:`OutputFile` writes ``NAME.partial`` under an
exclusive lock and renames it onto ``NAME`` once complete (a crash leaves ``NAME`` as it was);
non-regular files and the shell's streams are written in place. Written in one go: atomic."""
from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import re
import sys
from pathlib import Path

from regressor.errors import SilhouettePoseError

PARTIAL_SUFFIX = ".partial"
#: The longest file name, in bytes, of the usual file systems (ext4, XFS, btrfs, tmpfs).
NAME_MAX = 255


class _FileError(SilhouettePoseError, RuntimeError):
    """One line starting with the file's path; ``path`` (or None) names the option it came from."""

    def __init__(self, message: str, path: str | Path | None = None):
        super().__init__(message)
        self.path = None if path is None else Path(path)


class OutputBusyError(_FileError):
    """Another process is writing the same output; one line naming the file."""


class OutputWriteError(_FileError):
    """Writing an output failed (disk full, I/O error); one line naming the file."""


class ClosedOnExit:
    """A sink that a ``with`` block closes (close()) on leaving."""

    def __enter__(self):
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


_STREAM = re.compile(r"/(?:proc/self|dev)/fd/(\d+)|/dev/std(in|out|err)")


def stream_descriptor(path: str | Path) -> int | None:
    """N when ``path`` is, or links to, /dev/std*, /dev/fd/N or /proc/self/fd/N: a stream the
    shell opened (a pipe, a terminal, > or >>), written through N to keep offset and append."""
    current = os.path.abspath(path)
    for _ in range(40):                  # the kernel's own limit on a chain of links
        match = _STREAM.fullmatch(current)
        if match:
            return int(match[1]) if match[1] else ("in", "out", "err").index(match[2])
        try:
            link = os.readlink(current)
        except OSError:
            return None
        current = os.path.normpath(os.path.join(os.path.dirname(current), link))
    return None


def beside_name(path: str | Path, suffix: str) -> Path:
    """``path`` with ``suffix`` added to its name. Past NAME_MAX bytes, NAME is cut and ``~`` and
    12 hex digits of its SHA-256 follow: the same NAME always gives the same name."""
    path = Path(path)
    name = path.name + suffix
    if len(os.fsencode(name)) <= NAME_MAX:
        return path.with_name(name)
    digest = hashlib.sha256(os.fsencode(path.name)).hexdigest()[:12]
    keep = NAME_MAX - len(os.fsencode(suffix)) - len(digest) - 1
    head = os.fsencode(path.name)[:keep].decode(sys.getfilesystemencoding(), "ignore")
    return path.with_name(f"{head}~{digest}{suffix}")


def partial_path(path: str | Path) -> Path:
    """Where ``path`` is written until it is complete: ``NAME.partial`` beside it."""
    return beside_name(path, PARTIAL_SUFFIX)


def file_identity(path: str | Path) -> tuple:
    """What makes paths the same file: (device, inode) if it exists, else the resolved path."""
    try:
        status = os.stat(path)
        return ("inode", status.st_dev, status.st_ino)
    except OSError:
        return ("path", os.path.realpath(path))


def same_file(path: Path, fd: int) -> bool:
    """Whether ``path`` still names the file open as ``fd`` (not renamed or removed since)."""
    try:
        return os.stat(path).st_ino == os.fstat(fd).st_ino
    except FileNotFoundError:
        return False


def open_locked(path: Path, flags: int) -> int:
    """A descriptor of ``path`` (created), locked exclusively; OutputBusyError when held."""
    for _ in range(10):
        fd = os.open(path, flags | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            from tracker.outputs.failures import busy_error     # only on a refusal
            raise busy_error(path) from None
        except BaseException:
            os.close(fd)
            raise
        if same_file(path, fd):
            return fd
        os.close(fd)     # we locked a file nobody will look at: start again on the current one
    from tracker.outputs.failures import busy_error
    raise busy_error(path, changing=True)


def holds_data(path: Path) -> bool:
    """Whether ``path`` is a non-empty regular file."""
    try:
        return path.is_file() and path.stat().st_size > 0
    except OSError:
        return False


class OutputFile:
    """A binary output written beside ``path`` and renamed onto it by commit(). File protocol:
    write(bytes) (handed to the system at once: records survive a kill), tell(), flush()."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        stream = stream_descriptor(self.path)
        #: The bytes go straight to the destination (a pipe, a device): nothing can be taken back.
        self.in_place = stream is not None or (self.path.exists() and not self.path.is_file())
        self._target = self.path if self.in_place else Path(os.path.realpath(self.path))
        self._written = self.path if self.in_place else partial_path(self._target)
        try:
            if stream is not None:
                self._fd = os.dup(stream)
            elif self.in_place:
                self._fd = os.open(self.path, os.O_WRONLY)
            else:
                if holds_data(self._written):      # an earlier run's unfinished output
                    from tracker.outputs.aside import set_aside
                    set_aside(self._written)
                self._fd = open_locked(self._written, os.O_WRONLY)
                os.ftruncate(self._fd, 0)   # set_aside kept any data it held
        except OSError as exc:
            raise OutputWriteError(f"{self._written}: cannot write ({exc.strerror})",
                                   self._written) from None
        self._offset = 0

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
        """Nothing: write() hands every byte to the operating system."""

    def commit(self) -> None:
        """Flush to disk and rename onto the destination (replacing it); idempotent."""
        if self._fd < 0:
            return
        try:
            if not self.in_place:
                os.fsync(self._fd)
                os.replace(self._written, self._target)
                sync_folder(self._target.parent)
        except OSError as exc:
            self.discard(keep=True)
            raise OutputWriteError(f"{self.path}: could not be finished ({exc.strerror}); the "
                                   f"data written is in {self._written}", self.path) from None
        fd, self._fd = self._fd, -1
        os.close(fd)   # also releases the lock

    def discard(self, keep: bool = False) -> None:
        """Stop without touching the destination; remove the partial file unless ``keep``."""
        if self._fd < 0:
            return
        fd, self._fd = self._fd, -1
        os.close(fd)
        if not keep and not self.in_place:
            with contextlib.suppress(OSError):
                os.unlink(self._written)


def sync_folder(folder: Path) -> None:
    """Make a rename in ``folder`` durable (best effort: not every file system allows it)."""
    with contextlib.suppress(OSError):
        fd = os.open(folder if str(folder) else ".", os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
