"""Frames evenly spaced over a stream whose frames cannot be picked by number (unknown length,
or a variable rate's start time), in one pass; imported only for such streams."""
from __future__ import annotations

import warnings

import cv2
import numpy as np

from tracker.video.decode import VideoSource, _file_state, _open_capture, _seek


def sample_by_time(source: VideoSource, count: int, size: tuple[int, int] | None
                   ) -> list[np.ndarray]:
    """VideoSource.sample_frames over the frames iteration yields (the time range), its
    warnings left to the tracking pass."""
    sample = _EvenSample(count)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for n, frame in enumerate(source):
            if sample.wants(n):
                image = frame.image
                if size is not None and size != (image.shape[1], image.shape[0]):
                    image = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
                sample.keep(image)
    return sample.frames()


def sample_through(source: VideoSource, count: int, size: tuple[int, int] | None
                   ) -> list[np.ndarray]:
    """VideoSource.sample_frames over a stream of unknown length, in one pass to its end (or
    its live end, as in iteration)."""
    capture = _open_capture(source.path)
    opened = _file_state(source.path)
    sample, give_up = _EvenSample(count), source.unreadable_run()
    try:
        index = _seek(capture, source.start_index, give_up)
        offset, failed = index, 0
        while failed < give_up:
            if not capture.grab():
                if _file_state(source.path) != opened:
                    break
                failed, index = failed + 1, index + 1
                continue
            failed = 0
            if sample.wants(index - offset):
                ok, image = capture.retrieve()
                sample.keep(source._prepare(image, size) if ok and image is not None
                            else None)
            index += 1
    finally:
        capture.release()
    return sample.frames()


class _EvenSample:
    """Up to ``count`` frames evenly spaced over a stream of unknown length, in one pass:
    every ``step``-th frame is kept, and when 2 count are kept every other one is dropped and
    ``step`` doubles; :meth:`frames` picks ``count`` evenly from what is kept."""

    def __init__(self, count: int):
        self.count, self.step, self.kept = count, 1, []

    def wants(self, n: int) -> bool:
        """Whether the n-th frame (from 0) is one to keep."""
        return n % self.step == 0

    def keep(self, image: np.ndarray | None) -> None:
        """Keep a wanted frame (None: it did not decode, nothing kept)."""
        if image is not None:
            self.kept.append(image)
        if len(self.kept) >= 2 * max(self.count, 1):
            self.kept, self.step = self.kept[::2], 2 * self.step

    def frames(self) -> list[np.ndarray]:
        if len(self.kept) <= self.count:
            return self.kept
        picks = np.unique(np.linspace(0, len(self.kept) - 1, self.count).round().astype(int))
        return [self.kept[i] for i in picks]
