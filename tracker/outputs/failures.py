"""The one-line messages of outputs that fail: a sink's error, an output locked or replaced by
another process (imported only then)."""
from __future__ import annotations

from pathlib import Path

from tracker.outputs.files import OutputBusyError, OutputWriteError


def problem_line(sink, exc: BaseException) -> str:
    """One line for a sink's failure, led by its ``option`` ("--json /dev/full: No space left on
    device": an OutputWriteError starts with its file; "--view: ...") or else its class."""
    option = getattr(sink, "option", None)
    if option is None:
        return f"{type(sink).__name__}: {exc}"
    return f"{option} {exc}" if isinstance(exc, OutputWriteError) else f"{option}: {exc}"


def busy_error(path: Path, changing: bool = False) -> OutputBusyError:
    """The error for an output another process holds locked (or keeps replacing)."""
    problem = ("kept changing while being locked; another track run is writing this output"
               if changing else "another track run is writing this output; wait for it to "
               "finish or choose another file name")
    return OutputBusyError(f"{path}: {problem}", path)
