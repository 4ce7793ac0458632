"""Shrinking frames by area averaging (OpenCV's INTER_AREA), fast for any ratio: INTER_AREA's
exact halving is fast, so :func:`shrink` halves while it can, then takes one general step
(about half the time; pixels at sharp edges move by about a grey level: docs/tuning.md)."""
from __future__ import annotations

import cv2
import numpy as np


def shrink(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """image (H, W) or (H, W, C) shrunk to ``size`` (width, height) px, each no larger than
    the image's, by area averaging; the image itself when it already has that size."""
    width, height = int(size[0]), int(size[1])
    while (image.shape[1] % 2 == 0 and image.shape[0] % 2 == 0
           and image.shape[1] // 2 >= width and image.shape[0] // 2 >= height):
        image = cv2.resize(image, (image.shape[1] // 2, image.shape[0] // 2),
                           interpolation=cv2.INTER_AREA)
    if (image.shape[1], image.shape[0]) != (width, height):
        image = cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA)
    return image
