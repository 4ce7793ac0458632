"""Reading a video from a frame past the first (a start time, samples too sparse to read
straight through): imported only then."""
from __future__ import annotations

import cv2
import numpy as np

from tracker.video import decode


def seek(capture: cv2.VideoCapture, start_index: int, give_up: int) -> int:
    """decode._seek for a ``start_index`` past 0: a container seek, else decoding and discarding
    frames (some codecs only seek to key frames), ``give_up`` undecodable frames in a row
    ending the stream (it then returns the index reached)."""
    capture.set(cv2.CAP_PROP_POS_FRAMES, start_index)
    position = int(capture.get(cv2.CAP_PROP_POS_FRAMES))
    if position == start_index:
        return start_index
    capture.set(cv2.CAP_PROP_POS_FRAMES, 0)
    failed = 0                   # a damaged frame on the way is passed over, as in iteration
    for index in range(start_index):
        if capture.grab():
            failed = 0
        else:
            failed += 1
            if failed >= give_up:
                return index - failed + 1
    return start_index


def seek_missed(source: decode.VideoSource, decoded: bool, capture: cv2.VideoCapture) -> bool:
    """Whether the first read after seeking to ``source``'s start frame shows a variable rate's
    start time elsewhere: nothing decodes there, or its container time is past the start."""
    return not decoded or capture.get(cv2.CAP_PROP_POS_MSEC) / 1000.0 > \
        source.start_s + 1.0 / source.fps + 1e-6


def sample_by_seeking(source: decode.VideoSource, indices: np.ndarray,
                      size: tuple[int, int] | None) -> list[np.ndarray]:
    """VideoSource.sample_frames of frames ``indices`` (sorted, more than SEQUENTIAL_SPACING
    apart), each sought; stops at the first frame it cannot seek to."""
    capture = decode._open_capture(source.path)
    images = []
    give_up = source.unreadable_run()
    try:
        for index in indices:
            if decode._seek(capture, int(index), give_up) != index:
                break
            ok, image = capture.read()
            if ok and image is not None:
                images.append(source._prepare(image, size))
    finally:
        capture.release()
    return images
