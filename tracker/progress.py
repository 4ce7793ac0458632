"""Progress bar on stderr for long videos: frames done, frames per second, people in view.

Quiet when stderr is not a terminal (pipes, CI, logs) or when asked to be.
"""
from __future__ import annotations

import sys

from tqdm import tqdm


class Progress:
    """total: frames expected (None if unknown); quiet: never draw."""

    def __init__(self, total: int | None, quiet: bool = False, stream=None):
        stream = sys.stderr if stream is None else stream
        enabled = not quiet and hasattr(stream, "isatty") and stream.isatty()
        self._bar = tqdm(total=total, unit="frame", file=stream, dynamic_ncols=True,
                         mininterval=0.25) if enabled else None

    def update(self, people_in_view: int) -> None:
        """One more frame done, with this many people tracked in it."""
        if self._bar is not None:
            self._bar.update(1)
            self._bar.set_postfix_str(f"people {people_in_view}", refresh=False)

    def close(self) -> None:
        """Finish the bar (idempotent)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None
