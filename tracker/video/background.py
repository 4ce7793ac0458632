"""The empty scene without a clean plate: a background image and where it cannot be trusted (a
person who never leaves the spot is in every per-pixel statistic, but makes their pixels often
unlike the median). There colour decides (tracker.video.zone), elsewhere background subtraction."""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class ClipBackground:
    """``image``: BGR uint8 (h, w, 3) background estimate at working size; ``unreliable``: bool
    (h, w), True where the estimate may show a person (empty for a clean plate)."""

    image: np.ndarray
    unreliable: np.ndarray


def clean_plate(image: np.ndarray) -> ClipBackground:
    """A background known to be empty (BGR uint8 (h, w, 3)): trusted everywhere."""
    return ClipBackground(image, np.zeros(image.shape[:2], bool))


#: A global brightness gain further than this from 1 is undone before subtraction and before
#: the clip's busy pixels are counted.
MIN_GAIN_CHANGE = 0.03


def clip_background(frames: np.ndarray, tolerance: float = 20.0, max_busy: float = 0.25,
                    close_px: int = 9, bridge_px: int = 31,
                    min_gain_change: float = MIN_GAIN_CHANGE,
                    median: np.ndarray | None = None) -> ClipBackground:
    """Background and its unreliable zone from frames (N, h, w, 3) BGR uint8 spread over a clip:
    pixels off the median by over ``tolerance`` grey levels in some channel in over ``max_busy``
    of the frames (a person on the spot, not a passer-by), opened, closed by ``close_px`` px,
    along rows by ``bridge_px`` px under zone above (still legs under a busy torso), holes
    filled. Frames with a gain over the median beyond ``min_gain_change`` are undone first.
    ``median``: the frames' per-pixel median (median_background's) when known already."""
    stack = np.asarray(frames)
    if median is None:
        median = np.median(stack, axis=0).astype(np.uint8)
    meter = GainMeter(median)
    gains = [meter(frame) for frame in stack]
    changed = [np.all(g > 0) and np.abs(g - 1).max() > min_gain_change for g in gains]
    if any(changed):
        stack = np.stack([undo_gain(frame, gain) if change else frame
                          for frame, gain, change in zip(stack, gains, changed)])
        median = np.median(stack, axis=0).astype(np.uint8)
    busy = np.zeros(median.shape[:2], np.float32)
    for frame in stack:
        busy += cv2.absdiff(frame, median).max(axis=2) > tolerance
    zone = ((busy / len(stack)) > max_busy).astype(np.uint8) * 255
    zone = cv2.morphologyEx(zone, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    if close_px > 1:
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (close_px, close_px))
        zone = cv2.morphologyEx(zone, cv2.MORPH_CLOSE, kernel)
    if bridge_px > 1:
        bridged = cv2.morphologyEx(zone, cv2.MORPH_CLOSE, np.ones((1, bridge_px), np.uint8))
        below = np.zeros_like(zone)                       # zone somewhere above in the column
        below[1:] = np.maximum.accumulate(zone, axis=0)[:-1]
        zone = np.maximum(zone, cv2.bitwise_and(bridged, below))
    return ClipBackground(median, fill_holes(zone) > 0)


def fill_holes(mask: np.ndarray) -> np.ndarray:
    """uint8 (h, w) mask (255 = set) with every enclosed hole filled."""
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    filled = np.zeros_like(mask)
    cv2.drawContours(filled, contours, -1, 255, cv2.FILLED)
    return filled


def undo_gain(frame: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """``frame`` (BGR uint8 (h, w, 3)) divided by its per-channel ``gain`` (3,) over a
    background (GainMeter), saturating at 255: its brightness brought to the background's."""
    return cv2.multiply(frame, tuple(float(1 / g) for g in gain) + (0.0,), dtype=cv2.CV_8U)


class GainMeter:
    """Per-channel brightness gain (3,) of a frame over one background (both BGR uint8
    (h, w, 3)), called with the frame: the median ratio on every ``step``-th pixel (people
    cover a minority of the image). The background's samples are prepared once."""

    def __init__(self, background: np.ndarray, step: int = 8):
        self.step = step
        b = self._channels(background)                                      # (3, n)
        self._usable = (b > 16).all(axis=0) & (b < 240).all(axis=0)
        self._background = b

    def _channels(self, image: np.ndarray) -> np.ndarray:
        """Every ``step``-th pixel of ``image`` (h, w, 3) as float32 (3, n), channel by channel."""
        sampled = image[::self.step, ::self.step]
        return np.moveaxis(sampled, 2, 0).reshape(3, -1).astype(np.float32)

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        f = self._channels(frame)
        ok = self._usable & (f < 250).all(axis=0)
        ratio = np.compress(ok, f, axis=1)                                  # (3, n ok)
        if ratio.shape[1] < 16:
            return np.ones(3, np.float32)
        ratio /= np.compress(ok, self._background, axis=1)
        return row_medians(ratio)


def row_medians(values: np.ndarray) -> np.ndarray:
    """np.median(values, axis=1) of float32 (3, n) without NaN, by a partial sort in place."""
    half = values.shape[1] // 2
    if values.shape[1] % 2:
        values.partition(half, axis=1)
        return values[:, half].copy()
    values.partition((half - 1, half), axis=1)
    return (values[:, half - 1] + values[:, half]) / np.float32(2)
