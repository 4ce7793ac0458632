"""The scripts' argument parser: ``track``'s one-line OneLineParser (tracker.cli) with
check_outputs, and stops_in_one_line for a script's main (``track`` itself loads neither)."""
from __future__ import annotations

import os
import sys
import warnings
from collections.abc import Callable
from pathlib import Path

from tracker import cli
from tracker.cli import EXIT_INTERRUPTED, EXIT_USAGE, quiet_decoder_logs  # noqa: F401 (theirs)


def stops_in_one_line(prog: str, main: Callable[[list[str] | None], int]
                      ) -> Callable[[list[str] | None], int]:
    """A script's main(argv) that ends on Ctrl-C with "PROG: interrupted" on stderr and
    EXIT_INTERRUPTED, not a traceback, and prints warnings as one line "PROG: warning: ...",
    without Python's file name and source line."""
    def stopping(argv: list[str] | None = None) -> int:
        try:
            with warnings.catch_warnings():
                warnings.showwarning = cli.one_line_warning(prog)
                return main(argv)
        except KeyboardInterrupt:
            print(f"{prog}: interrupted", file=sys.stderr)
            return EXIT_INTERRUPTED
    stopping.__doc__ = main.__doc__
    return stopping


class OneLineParser(cli.OneLineParser):
    """tracker.cli.OneLineParser (one-line usage errors, status 2) with check_outputs."""

    def check_outputs(self, outputs, inputs=()) -> None:
        """Refuse, before any work, output files a script could not write or that would
        overwrite one of its inputs or another output: ``outputs`` and ``inputs`` are
        (option or description, path or None) pairs, e.g. [("--json", args.json)] and
        [("--model", args.model)]; None entries are skipped. An output may not be a folder,
        the folder of the file it names (a symlink followed) must exist and be writable (but
        for /dev/null and the like, written in place: tracker.outputs.whole_files.write_whole), and
        it may not be the same file as an input or another output, also through a relative
        path, a symlink or a hard link. Inputs that are one another (a folder of links) are
        no conflict. Exits as error() does."""
        # deferred: numpy
        from tracker.outputs.files import file_identity
        from tracker.outputs.whole_files import temporary_names
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
            for temporary in temporary_names(target):
                other = seen.get(file_identity(temporary))
                if other is not None:
                    self.error(f"{what} {path} is written as {temporary} until complete, which "
                               f"is {other[0]} {other[1]}; choose another file name")
            seen[key] = (what, path)
