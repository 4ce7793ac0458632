"""The one base class of every error this project raises on purpose.

Here, in ``regressor`` (which imports neither of the other packages), so that ``regressor``,
``sequences`` and ``tracker`` can all derive from it. Each subclass carries a one-line message
in the user's terms; the ``track`` command prints it and exits 1. Subclasses also derive from
the built-in class that fits (ValueError for bad input, RuntimeError for a failed step).
"""
from __future__ import annotations


class SilhouettePoseError(Exception):
    """A problem the user can act on (file, option, input); str() is a one-line message."""
