"""The background sample's pass shared with a second process (track with the frame worker,
whose second core idles until tracking starts): a forked helper reads the second half of the
frames from a seek while the caller reads on from the start. The halves are joined only where
the helper's first frame is the caller's own decoding of it (the same pixels and container
time) and the helper met no damaged frame; else the caller reads on alone. Either way the
samples are those of the one sequential pass; imported only when a second process may run."""
from __future__ import annotations

import contextlib
import hashlib
import multiprocessing
import os
import signal

import cv2
import numpy as np

#: Fewer frames than this between the first and last sample are read by the caller alone (the
#: fork and the helper's seek would cost about what they save).
MIN_SPLIT_FRAMES = 120
#: Samples larger than this in all (bytes; full-size 4K frames) are not sent through a pipe.
MAX_SPLIT_BYTES = 64 * 2 ** 20


def worth_splitting(indices: np.ndarray, size: tuple[int, int]) -> bool:
    """Whether sorted frame ``indices``, sampled at ``size`` (width, height) px, span enough
    frames to share their pass, and are small enough to pass between processes."""
    return len(indices) >= 4 and int(indices[-1] - indices[0]) >= MIN_SPLIT_FRAMES and \
        size[0] * size[1] * 3 * len(indices) <= MAX_SPLIT_BYTES


def _digest(image: np.ndarray) -> bytes:
    return hashlib.blake2b(np.ascontiguousarray(image).data, digest_size=16).digest()


class SampleHelper:
    """A forked process reading ``source``'s frames ``indices`` (sorted) from the middle one
    on, prepared at ``size`` as VideoSource._prepare does. The caller's pass hands it each
    frame it decodes (:meth:`rest`); close it."""

    def __init__(self, source, indices: np.ndarray, size: tuple[int, int] | None):
        self.middle = int(indices[len(indices) // 2])
        self._own: tuple[bytes, float] | None = None
        context = multiprocessing.get_context("fork")
        self._reader, writer = context.Pipe(duplex=False)
        wanted = [int(i) for i in indices if i >= self.middle]
        self._process = context.Process(target=_help, name="silhouette-pose sample helper",
                                        args=(self._reader, writer, source, wanted, size),
                                        daemon=True)
        threads = cv2.getNumThreads()
        cv2.setNumThreads(1)            # a child resizing a thread pool it inherited can hang
        stops = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, stops)  # none before its handlers
        try:
            self._process.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
            cv2.setNumThreads(threads)
        writer.close()
        self.done = False

    def rest(self, index: int, image: np.ndarray | None, capture: cv2.VideoCapture
             ) -> list[np.ndarray] | None:
        """After the caller decoded frame ``index`` (``image``: it raw, when it is a sample):
        the helper's samples after ``index`` once they are in and join, else None (read on)."""
        if self.done or index < self.middle:
            return None
        if index == self.middle and image is not None:
            self._own = (_digest(image), capture.get(cv2.CAP_PROP_POS_MSEC))
        if self._own is None or not self._reader.poll():
            self.done = self._own is None
            return None
        self.done = True
        try:
            first, samples = self._reader.recv()
        except (EOFError, OSError, TypeError, ValueError):
            return None
        if first != self._own:
            return None
        return [sample for i, sample in samples if i > index]

    def close(self) -> None:
        """End the helper (at once if it still runs) and release the pipe."""
        self.done = True
        self._reader.close()
        if self._process.is_alive():
            self._process.terminate()
        self._process.join(timeout=5.0)
        if self._process.is_alive():
            self._process.kill()
            self._process.join()


def _help(reader, writer, source, wanted: list[int], size) -> None:
    """The helper process: send ((digest, container ms) of the first wanted frame, [(index,
    prepared image)]) for frames ``wanted`` read from a seek to the first, or None when the
    seek misses or any frame there fails to decode."""
    reader.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)         # Ctrl-C is the caller's
    for number in (signal.SIGTERM, signal.SIGHUP):       # close() ends the helper by SIGTERM
        signal.signal(number, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, (signal.SIGINT, signal.SIGTERM, signal.SIGHUP))
    try:
        message = None
        with contextlib.suppress(Exception):
            message = _read_from_seek(source, wanted, size)
        writer.send(message)
    except (BrokenPipeError, ConnectionResetError):
        pass                                             # the caller has gone: so do we
    finally:
        writer.close()
        os._exit(0)                                      # no atexit handlers of the parent's


def _read_from_seek(source, wanted: list[int], size):
    """_help's message: None unless every frame from wanted[0] to wanted[-1] decodes."""
    capture = cv2.VideoCapture(str(source.path), cv2.CAP_ANY)
    try:
        capture.set(cv2.CAP_PROP_POS_FRAMES, wanted[0])
        if not capture.isOpened() or int(capture.get(cv2.CAP_PROP_POS_FRAMES)) != wanted[0]:
            return None
        keep, samples, first = set(wanted), [], None
        for index in range(wanted[0], wanted[-1] + 1):
            if not capture.grab():
                return None
            if index in keep:
                ok, image = capture.retrieve()
                if not ok or image is None:
                    return None
                if first is None:
                    first = (_digest(image), capture.get(cv2.CAP_PROP_POS_MSEC))
                samples.append((index, source._prepare(image, size)))
        return first, samples
    finally:
        capture.release()
