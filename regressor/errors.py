"""The base class of every error this project raises on purpose, in ``regressor`` (which imports
neither other package) so all three derive from it. Subclasses also derive from the built-in
that fits (ValueError for bad input, RuntimeError for a failed step); ``track`` prints the
message and exits 1.
"""
from __future__ import annotations


class SilhouettePoseError(Exception):
    """A problem the user can act on (file, option, input); str() is a one-line message."""
