"""Decoding, silhouettes and descriptors in a second process, so that ``track`` uses two cores:
a forked worker runs each frame's first half (PoseTracker.find_people, .describe) ahead on its
own copy of the tracker, one thread, for the same results (figures: docs/tuning.md). It ignores
Ctrl-C, exits when its reader has gone; its errors and warnings reach the main process in order."""
from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import time
import warnings
from collections.abc import Iterator

import cv2

from regressor.errors import SilhouettePoseError
from tracker import STOP_SIGNALS

#: Frames per message (and per regression batch, also in one process: the same results):
#: the pipe's cost negligible, the worker never far ahead, a live output little late.
BATCH_FRAMES = 16
#: Of every MAIN_DESCRIBES[1] frames, the first MAIN_DESCRIBES[0] are described by the main
#: process instead (sent with descriptions None), to balance the two halves' costs.
MAIN_DESCRIBES = (3, 4)


def described_chunks(source, tracker, batch: int, leave_to_main: bool = False
                     ) -> Iterator[list[tuple]]:
    """The first half of the tracking: lists of ``batch`` consecutive (frame_index, time_s,
    frame, people, descriptions); leave_to_main: descriptions None for the frames the main
    process describes. An error is raised after a last list of the frames before it."""
    share, period = MAIN_DESCRIBES
    stages = tracker.stage_seconds
    chunk: list[tuple] = []
    try:
        clock = time.perf_counter()
        for index, time_s, frame in source:
            stages["decode"] += time.perf_counter() - clock
            people = tracker.find_people(frame)
            descriptions = (None if leave_to_main and index % period < share
                            else [tracker.describe(p) for p in people])
            chunk.append((index, time_s, frame, people, descriptions))
            if len(chunk) == batch:
                yield chunk
                chunk = []
            clock = time.perf_counter()
    except GeneratorExit:
        raise
    except BaseException:
        if chunk:
            yield chunk
        raise
    if chunk:
        yield chunk


class FrameWorkerError(SilhouettePoseError, RuntimeError):
    """The worker process failed in a way that has no exception of its own to pass on."""


def can_fork() -> bool:
    """Whether this platform starts processes by fork (Linux, macOS): the worker needs it."""
    return "fork" in multiprocessing.get_all_start_methods()


class FrameWorker:
    """described_chunks over ``source`` with a copy of the primed ``tracker`` in a forked
    process; then ``stage_seconds``, ``frames_read`` and ``truncated`` are its. Close it."""

    def __init__(self, source, tracker, batch: int = BATCH_FRAMES):
        self.stage_seconds: dict[str, float] = {}
        self.frames_read, self.truncated = 0, False
        context = multiprocessing.get_context("fork")
        self._reader, writer = context.Pipe(duplex=False)
        self._process = context.Process(target=_work, name="silhouette-pose frame worker",
                                        args=(self._reader, writer, source, tracker, batch),
                                        daemon=True)
        # Set before the fork: a child resizing a thread pool it inherited can hang.
        threads = cv2.getNumThreads()
        cv2.setNumThreads(1)
        # Stop signals wait until the child has its own handlers (a Ctrl-C reaches both).
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
        try:
            self._process.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
            cv2.setNumThreads(threads)
        writer.close()           # the worker's end: its death then ends our reads

    def chunks(self) -> Iterator[list[tuple]]:
        """described_chunks' lists, frames left out; its warnings issued, its error raised."""
        while True:
            try:
                kind, payload = self._reader.recv()
            except EOFError:
                self._process.join(timeout=1.0)
                raise FrameWorkerError(f"the frame worker stopped unexpectedly (exit code "
                                       f"{self._process.exitcode})") from None
            if kind == "warnings":
                for message, category in payload:
                    warnings.warn(message, category, stacklevel=3)
            elif kind == "error":
                raise payload
            elif kind == "frames":
                yield payload
            elif kind == "end":
                self.stage_seconds, self.frames_read, self.truncated = payload
                return
            else:
                raise FrameWorkerError(f"the frame worker sent {kind!r} out of turn")

    def close(self) -> None:
        """Stop the worker (at once if it is still running) and release the pipe."""
        self._reader.close()
        if self._process.is_alive():
            self._process.terminate()
        self._process.join(timeout=5.0)
        if self._process.is_alive():
            self._process.kill()
            self._process.join()


def _work(reader, writer, source, tracker, batch: int) -> None:
    """The worker process: send each frame's people and descriptions."""
    # The fork's copy of the reading end closed: a send fails once the main process has gone.
    reader.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)      # Ctrl-C is the main process's
    for number in (signal.SIGTERM, signal.SIGHUP):    # close() ends the worker by SIGTERM
        signal.signal(number, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
    caught: list = []

    def send(message) -> None:
        """Send the warnings caught since the last message, then the message."""
        if caught:
            writer.send(("warnings", [(str(w.message), w.category) for w in caught]))
            caught.clear()
        writer.send(message)
    try:
        from threadpoolctl import threadpool_limits
        with threadpool_limits(1), warnings.catch_warnings(record=True) as caught:
            tracker.stage_seconds.clear()
            # The other core is the main process's: a second decoding thread only contends.
            source.decoder_threads = 1
            for chunk in described_chunks(source, tracker, batch, leave_to_main=True):
                send(("frames", [(index, time_s, people, descriptions)
                                 for index, time_s, _, people, descriptions in chunk]))
            send(("end", (dict(tracker.stage_seconds), source.frames_read, source.truncated)))
    except (BrokenPipeError, ConnectionResetError):
        pass                                          # the main process has gone: so do we
    except BaseException as error:                    # noqa: BLE001 - passed on, not hidden
        with contextlib.suppress(BrokenPipeError, ConnectionResetError):
            try:
                send(("error", error))
            except Exception:                         # noqa: BLE001 - one that does not pickle
                send(("error", FrameWorkerError(f"{type(error).__name__}: {error}")))
    finally:
        writer.close()
        os._exit(0)                                   # no atexit handlers of the parent's
