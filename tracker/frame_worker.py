"""Decoding, silhouettes and descriptors in a second process, so that ``track`` uses two cores.

A frame's work splits in two halves of about the same cost: decoding, background subtraction
and describing each silhouette, then association, regression, the front/back filters, the
skeleton and the outputs (figures: docs/tuning.md). The first half needs nothing from the second
(PoseTracker.find_people and .describe depend only on the frames and the settings), so a
worker process runs it ahead on its own copy of the tracker: both cores busy, the results the
same as in one process.

The worker is forked (the model is already in memory: no second load, no pickling) with
OpenCV and BLAS held to one thread each. It sends frames in small batches through a pipe; the
main process reads them in order. Ctrl-C is the main process's to handle (the worker ignores
it); the worker is terminated on close, and one whose reader has died fails on its next send
and exits. An error in the worker is raised in the main process as the same exception, after
the frames before it; its warnings are issued there too.
"""
from __future__ import annotations

import multiprocessing
import os
import signal
import time
import warnings
from collections.abc import Iterator

import cv2

from regressor.errors import SilhouettePoseError

#: Frames sent per message: enough to make the pipe's cost negligible, few enough that the
#: worker is never far ahead (memory) and a live output lags by a fraction of a second. The
#: main process regresses each message's frames in one batch (PoseTracker.track_frames), and
#: one process batches its frames the same way (tracker.run), so both give the same results.
BATCH_FRAMES = 8
#: Of every MAIN_DESCRIBES[1] frames, the first MAIN_DESCRIBES[0] have their people described
#: by the main process instead (their descriptions are sent as None): with the regression in
#: batches the worker's half became the longer one, and describing some frames over there
#: balances them; the results do not change (measurements: docs/tuning.md).
MAIN_DESCRIBES = (1, 2)


def main_describes(frame_index: int) -> bool:
    """Whether the main process describes this frame's people (MAIN_DESCRIBES)."""
    share, period = MAIN_DESCRIBES
    return frame_index % period < share


def described_chunks(source, tracker, batch: int, leave_to_main: bool = False
                     ) -> Iterator[list[tuple]]:
    """The first half of the tracking, for one process and for the worker alike: the frames
    of ``source`` with their people found and described by ``tracker``
    (PoseTracker.find_people, .describe), in lists of ``batch`` consecutive (frame_index,
    time_s, frame, people, descriptions), the last one shorter; the stage "decode" timed.
    leave_to_main: descriptions None for the frames the main process describes
    (main_describes). An error from the source or the tracker is raised after a last list of
    the frames before it, so that those are tracked too."""
    stages = tracker.stage_seconds
    chunk: list[tuple] = []
    try:
        clock = time.perf_counter()
        for index, time_s, frame in source:
            stages["decode"] += time.perf_counter() - clock
            people = tracker.find_people(frame)
            descriptions = (None if leave_to_main and main_describes(index)
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
    """Runs ``tracker``'s first half (PoseTracker.find_people and .describe) over ``source``
    in a forked process; :meth:`chunks` gives the frames in order, as the worker sends them.
    The tracker must be primed (PoseTracker.prime; tracker.run._prime): the worker
    starts from a copy of it, background model included, so the start-up is the one
    process's (priming in the worker, on the one thread it keeps to, took 0.2-0.4 s longer on
    the Pose2Sim views). After the last frame, :attr:`stage_seconds` holds the worker's
    stages (decode, silhouettes, descriptor) and :attr:`frames_read` / :attr:`truncated` the
    source's own. Close it (or use ``with``)."""

    def __init__(self, source, tracker, batch: int = BATCH_FRAMES):
        if not can_fork():
            raise FrameWorkerError("a frame worker needs a platform that can fork processes")
        self.stage_seconds: dict[str, float] = {}
        self.frames_read, self.truncated = 0, False
        context = multiprocessing.get_context("fork")
        self._reader, writer = context.Pipe(duplex=False)
        self._process = context.Process(target=_work, name="silhouette-pose frame worker",
                                        args=(self._reader, writer, source, tracker, batch),
                                        daemon=True)
        # OpenCV's thread count is set before the fork, never in the child: a child that
        # resizes a thread pool it inherited without its threads can hang (seen here).
        threads = cv2.getNumThreads()
        cv2.setNumThreads(1)
        try:
            self._process.start()
        finally:
            cv2.setNumThreads(threads)
        writer.close()           # the worker's end: its death then ends our reads

    def chunks(self) -> Iterator[list[tuple]]:
        """The frames as the worker sends them: lists of up to ``batch`` consecutive
        (frame_index, time_s, people, descriptions), every one full but the last;
        descriptions is None for the frames left to the main process to describe
        (MAIN_DESCRIBES)."""
        while True:
            kind, payload = self._receive()
            if kind == "frames":
                yield payload
            elif kind == "end":
                self.stage_seconds, self.frames_read, self.truncated = payload
                return
            else:
                raise FrameWorkerError(f"the frame worker sent {kind!r} out of turn")

    def _receive(self) -> tuple[str, object]:
        """The worker's next message (kind, payload); its warnings issued on the way, its
        error raised."""
        while True:
            try:
                kind, payload = self._reader.recv()
            except EOFError:
                self._process.join(timeout=1.0)
                raise FrameWorkerError(f"the frame worker stopped unexpectedly (exit code "
                                       f"{self._process.exitcode})") from None
            if kind != "warnings":
                break
            for message, category in payload:
                warnings.warn(message, category, stacklevel=4)
        if kind == "error":
            raise payload
        return kind, payload

    def close(self) -> None:
        """Stop the worker (at once if it is still running) and release the pipe."""
        self._reader.close()
        if self._process.is_alive():
            self._process.terminate()
        self._process.join(timeout=5.0)
        if self._process.is_alive():
            self._process.kill()
            self._process.join()

    def __enter__(self) -> "FrameWorker":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _work(reader, writer, source, tracker, batch: int) -> None:
    """The worker process: send each frame's people and descriptions."""
    # The fork copied the main process's end of the pipe: closed here, so that once the main
    # process has gone, no reader is left and the next send fails instead of blocking.
    reader.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)      # Ctrl-C is the main process's
    for number in (signal.SIGTERM, signal.SIGHUP):    # not the main process's handlers:
        signal.signal(number, signal.SIG_DFL)         # close() ends the worker by SIGTERM
    try:
        from threadpoolctl import threadpool_limits
        with threadpool_limits(1), warnings.catch_warnings(record=True) as caught:
            # (the filters stay the main process's, copied by the fork)
            writer = _PassingWarnings(writer, caught)
            tracker.stage_seconds.clear()
            for chunk in described_chunks(source, tracker, batch, leave_to_main=True):
                # the frames themselves stay here: the main process needs their people only
                writer.send(("frames", [(index, time_s, people, descriptions)
                                        for index, time_s, _, people, descriptions in chunk]))
            writer.send(("end", (dict(tracker.stage_seconds), source.frames_read,
                                 source.truncated)))
    except (BrokenPipeError, ConnectionResetError):
        pass                                          # the main process has gone: so do we
    except BaseException as error:                    # noqa: BLE001 - passed on, not hidden
        _send_error(writer, error)
    finally:
        writer.close()
        os._exit(0)                                   # no atexit handlers of the parent's


class _PassingWarnings:
    """The worker's end of the pipe, sending the warnings caught since the last message
    (e.g. a video cut short: tracker.video.decode.VideoTruncatedWarning) before each message, for the
    main process to issue in their place among the frames."""

    def __init__(self, writer, caught: list):
        self._writer, self._caught = writer, caught

    def send(self, message) -> None:
        if self._caught:
            self._writer.send(("warnings", [(str(w.message), w.category)
                                            for w in self._caught]))
            self._caught.clear()
        self._writer.send(message)

    def close(self) -> None:
        self._writer.close()


def _send_error(writer, error: BaseException) -> None:
    """Pass the worker's exception to the main process (as it is when it pickles, else as a
    FrameWorkerError with its message); the frames done before it were sent already
    (described_chunks)."""
    try:
        writer.send(("error", error))
    except (BrokenPipeError, ConnectionResetError):
        return
    except Exception:                                 # noqa: BLE001 - unpicklable exception
        try:
            writer.send(("error", FrameWorkerError(f"{type(error).__name__}: {error}")))
        except (BrokenPipeError, ConnectionResetError):
            return
