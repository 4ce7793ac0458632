"""Progress bar on stderr: frames done, frames per second, people in view; quiet when stderr
is not a terminal (pipes, CI, logs) or when asked to be."""
from __future__ import annotations

import sys
from collections.abc import Callable

from tqdm import tqdm


class Progress:
    """total: frames expected (None if unknown); quiet: never draw; after_update: called after
    each frame's update (``track``'s check for a stop signal that something swallowed)."""

    def __init__(self, total: int | None, quiet: bool = False,
                 after_update: Callable[[], None] = lambda: None):
        enabled = not quiet and hasattr(sys.stderr, "isatty") and sys.stderr.isatty()
        self._bar = tqdm(total=total, unit="frame", file=sys.stderr, dynamic_ncols=True,
                         mininterval=0.25) if enabled else None
        self._after_update = after_update

    def update(self, people_in_view: int) -> None:
        """One more frame done, with this many people tracked in it."""
        if self._bar is not None:
            self._bar.update(1)
            self._bar.set_postfix_str(f"people {people_in_view}", refresh=False)
        self._after_update()

    def close(self) -> None:
        """Finish the bar (idempotent)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None
