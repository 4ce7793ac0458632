"""Drawing calls made at their video times by a thread of their own, behind a bounded buffer.

Why: the live view plays the video at its own speed; waiting for each frame's time inside the
tracking loop let every pause of that loop (``--lag`` smooths a block of frames at a time)
reach the screen. The loop hands each call over and goes on tracking; tracking outruns the
video, so a pause shorter than the buffer's lead never shows (figures: docs/readme_notes.md).

The lead is bounded in video time (``lead_s``): ``put`` blocks while the oldest call not yet
made is more than lead_s older than the new one, so memory stays flat however fast tracking
is.
"""
from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

#: Seconds of video the tracker may run ahead of the screen: longer than any pause of the
#: tracking loop measured (about 0.14 s at --lag 5), short enough that a stop drops little.
DEFAULT_LEAD_S = 1.0


class Player:
    """Makes calls in the order given, each no sooner than its video time after the first
    call's (wall clock), on a daemon thread.

    lead_s: seconds of video the calls waiting may span (put blocks beyond it). The first
    exception a call raises is kept in ``error`` (the calls after it are dropped, so put never
    blocks for good); the owner re-raises it.
    """

    def __init__(self, lead_s: float = DEFAULT_LEAD_S, name: str = "playout"):
        if not lead_s > 0:
            raise ValueError(f"lead_s must be > 0, got {lead_s}")
        self.lead_s = float(lead_s)
        self.error: BaseException | None = None
        self._calls: deque = deque()         # (video time s, call, args)
        self._cond = threading.Condition()
        self._closing = self._stopped = False
        self._start: tuple[float, float] | None = None    # (video s, wall s) of the first call
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def put(self, time_s: float, call: Callable, *args) -> None:
        """Make call(*args) at video time time_s (seconds); waits while the buffer is full."""
        with self._cond:
            if self._closing:
                raise RuntimeError("the player is closed")
            while (self._calls and time_s - self._calls[0][0] > self.lead_s
                   and not self._stopped):
                self._cond.wait()
            self._calls.append((float(time_s), call, args))
            self._cond.notify_all()

    def discard(self) -> None:
        """Drop the calls not made yet (the one being made finishes)."""
        with self._cond:
            self._calls.clear()
            self._cond.notify_all()

    def close(self, drain: bool = True, timeout_s: float | None = None) -> None:
        """Make the calls waiting at their times (drain) or drop them, then stop the thread;
        idempotent. timeout_s: how long to drain at most (None: as long as it takes); the
        calls still waiting then are dropped (the one being made finishes)."""
        with self._cond:
            self._closing = True
            if not drain:
                self._calls.clear()
            self._cond.notify_all()
        self._thread.join(timeout_s)
        if self._thread.is_alive():
            self.discard()
            self._thread.join()

    def _ahead(self, time_s: float) -> float:
        """Seconds until time_s is due (the first call is due at once)."""
        now = time.perf_counter()
        if self._start is None:
            self._start = (time_s, now)
        return (time_s - self._start[0]) - (now - self._start[1])

    def _run(self) -> None:
        try:
            while True:
                with self._cond:
                    while True:
                        if not self._calls:
                            if self._closing:
                                return
                            self._cond.wait()
                            continue
                        ahead = self._ahead(self._calls[0][0])
                        if ahead > 0:
                            self._cond.wait(ahead)     # woken early by put/discard/close
                            continue
                        _, call, args = self._calls.popleft()
                        self._cond.notify_all()
                        break
                if self.error is None:
                    try:
                        call(*args)
                    except BaseException as exc:   # kept for the owner, who re-raises it
                        self.error = exc
        finally:
            with self._cond:
                self._stopped = True
                self._cond.notify_all()
