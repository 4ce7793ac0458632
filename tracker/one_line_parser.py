"""An argument parser whose usage errors are one line, for ``track`` and the scripts.

argparse's own error() prints the whole usage block before the message; a user who mistyped
one option then has to find the line that names it. Here the message alone is printed, with a
pointer to --help, and the exit status is argparse's (2).
"""
from __future__ import annotations

import argparse
import os
import sys
import warnings
from collections.abc import Callable
from pathlib import Path

EXIT_USAGE = 2                  # argparse's status for a usage error
EXIT_INTERRUPTED = 130          # the shell's status for a run ended by Ctrl-C (128 + SIGINT)


def quiet_decoder_logs() -> None:
    """Keep FFmpeg's and OpenCV's own log lines ("moov atom not found") off stderr, where
    they would repeat a one-line error in their words (TRACK_DEBUG set: left as they are).
    Both variables are read when the first video is opened: call before that. (Here, not
    beside the decoding, so that ``track`` need not load OpenCV to call it.)"""
    if not os.environ.get("TRACK_DEBUG"):
        os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
        os.environ.setdefault("OPENCV_LOG_LEVEL", "OFF")


def stops_in_one_line(prog: str, main: Callable[[list[str] | None], int]
                      ) -> Callable[[list[str] | None], int]:
    """A script's main(argv) that ends on Ctrl-C with "PROG: interrupted" on stderr and
    EXIT_INTERRUPTED, not a traceback, and prints warnings as one line "PROG: warning: ...",
    without Python's file name and source line."""
    def one_line(message, category, filename, lineno, file=None, line=None) -> None:
        print(f"{prog}: warning: {message}", file=sys.stderr)

    def stopping(argv: list[str] | None = None) -> int:
        try:
            with warnings.catch_warnings():
                warnings.showwarning = one_line
                return main(argv)
        except KeyboardInterrupt:
            print(f"{prog}: interrupted", file=sys.stderr)
            return EXIT_INTERRUPTED
    stopping.__doc__ = main.__doc__
    return stopping


class OneLineParser(argparse.ArgumentParser):
    """argparse.ArgumentParser whose error(message) prints ``PROG: error: MESSAGE (see PROG
    --help)`` on one line and exits with status 2."""

    def error(self, message):
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def check_outputs(self, outputs, inputs=()) -> None:
        """Refuse, before any work, output files a script could not write or that would
        overwrite one of its inputs or another output: ``outputs`` and ``inputs`` are
        (option or description, path or None) pairs, e.g. [("--json", args.json)] and
        [("--model", args.model)]; None entries are skipped. An output may not be a folder,
        the folder of the file it names (a symlink followed) must exist and be writable (but
        for /dev/null and the like, written in place: tracker.outputs.files.write_whole), and
        it may not be the same file as an input or another output, also through a relative
        path, a symlink or a hard link. Inputs that are one another (a folder of links) are
        no conflict. Exits as error() does."""
        from tracker.outputs.files import PARTIAL_SUFFIX, file_identity, partial_path  # deferred: numpy
        seen = {}
        for what, path in inputs:
            if path is not None:
                seen.setdefault(file_identity(path), (what, Path(path)))
        for what, path in outputs:
            if path is None:
                continue
            path = Path(path)
            target = Path(os.path.realpath(path))
            if target.is_dir():
                self.error(f"{what} {path} is a folder; give a file name")
            in_place = target.exists() and not target.is_file()
            if not target.parent.is_dir():
                self.error(f"{what} {path}: no folder {target.parent}")
            if (not in_place and not os.access(target.parent, os.W_OK)) or \
                    (target.exists() and not os.access(target, os.W_OK)):
                self.error(f"{what} {path}: not writable")
            key = file_identity(path)
            if key in seen:
                other, other_path = seen[key]
                self.error(f"{what} {path} is the same file as {other} {other_path}; choose "
                           f"another file name (nothing was written)")
            # Nor may the temporary names it is written under (write_whole's two forms) be
            # an input: a file found there is moved aside before writing.
            for temporary in (partial_path(target), target.with_name(
                    f"{target.stem}{PARTIAL_SUFFIX}{target.suffix}")):
                other = seen.get(file_identity(temporary))
                if other is not None:
                    self.error(f"{what} {path} is written as {temporary} until complete, which "
                               f"is {other[0]} {other[1]}; choose another file name")
            seen[key] = (what, path)
