"""An argument parser whose usage errors are one line, for ``track`` and the scripts.

argparse's own error() prints the whole usage block before the message; a user who mistyped
one option then has to find the line that names it. Here the message alone is printed, with a
pointer to --help, and the exit status is argparse's (2).
"""
from __future__ import annotations

import argparse

EXIT_USAGE = 2                  # argparse's status for a usage error


class OneLineParser(argparse.ArgumentParser):
    """argparse.ArgumentParser whose error(message) prints ``PROG: error: MESSAGE (see PROG
    --help)`` on one line and exits with status 2."""

    def error(self, message):
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")
