"""An argument parser whose usage errors are one line, for ``track`` and the scripts.

argparse's own error() prints the whole usage block before the message; a user who mistyped
one option then has to find the line that names it. Here the message alone is printed, with a
pointer to --help, and the exit status is argparse's (2).
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path

EXIT_USAGE = 2                  # argparse's status for a usage error


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
        its folder must exist and be writable, and no two entries (an input and an output or
        two outputs, also through a relative path, a symlink or a hard link) may be the same
        file. Exits as error() does."""
        from .sinks.files import OutputPathError, check_distinct     # deferred: numpy
        named = [(what, Path(path)) for what, path in inputs if path is not None]
        for what, path in outputs:
            if path is None:
                continue
            path = Path(path)
            if path.is_dir():
                self.error(f"{what} {path} is a folder; give a file name")
            folder = path.parent if str(path.parent) else Path(".")
            if not folder.is_dir():
                self.error(f"{what} {path}: no folder {folder}")
            if not os.access(folder, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
                self.error(f"{what} {path}: not writable")
            named.append((what, path))
        try:
            check_distinct(named)
        except OutputPathError as exc:
            self.error(str(exc))
