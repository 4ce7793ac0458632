"""``track --background``: the clean plate (an image of the empty scene) checked and read, and
checked against the video; loaded only when one is given."""
from __future__ import annotations

import os
import warnings
from pathlib import Path

import cv2
import numpy as np

from tracker.cli import TrackError
from tracker.run import BackgroundMismatchError
from tracker.video.unopenable import nothing_decodes
from tracker.video.background import GainMeter, undo_gain
from tracker.video.decode import VideoSource, colourless
from tracker.video.silhouettes import median_background

#: A clean plate is refused when, in most of these frames spread over the video, the frame
#: (its brightness brought to the plate's) differs from it all over: in more than
#: PLATE_MAX_CELLS of the cells of an 8 x 8 grid, over a tenth of the pixels differ by more
#: than PLATE_TOLERANCE grey levels. A person is one blob (the sample's walker touches about
#: 10 % of the cells against its plate, a mirrored plate 95 %).
PLATE_CHECK_FRAMES, PLATE_MAX_CELLS, PLATE_TOLERANCE = 5, 0.75, 25


def check_background_file(path: Path) -> None:
    """TrackError unless --background names a readable file."""
    if path.is_dir():
        raise TrackError(f"--background {path} is a folder; give an image file")
    if not path.exists():
        raise TrackError(f"--background {path}: no such file")
    if not path.is_file():
        raise TrackError(f"--background {path} is not a regular file; give an image file")
    if not os.access(path, os.R_OK):
        raise TrackError(f"--background {path}: not readable (permissions)")


def load_background(path: Path, source: VideoSource) -> np.ndarray:
    """The --background image as BGR uint8 at the video's size (TrackError if unreadable or
    of another shape; a one-line warning when it has to be resized)."""
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise TrackError(f"--background {path}: not an image OpenCV can read (PNG, JPEG, ...)")
    size = (source.width, source.height)
    if (image.shape[1], image.shape[0]) != size:
        if abs(image.shape[1] / image.shape[0] - size[0] / size[1]) > 0.02 * size[0] / size[1]:
            raise TrackError(f"--background {path} is {image.shape[1]}x{image.shape[0]}, the "
                             f"video {size[0]}x{size[1]}: not the same view")
        warnings.warn(f"--background {path} is {image.shape[1]}x{image.shape[0]}; resized to "
                      f"the video's {size[0]}x{size[1]}")
        image = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    return image


def _scaled_size(width: int, height: int, max_side: int) -> tuple[int, int]:
    """Frame size after shrinking so the longer side is at most ``max_side`` px (never enlarges)."""
    if max(width, height) <= max_side:
        return width, height
    scale = max_side / max(width, height)
    return max(1, round(width * scale)), max(1, round(height * scale))


def check_plate(source: VideoSource, plate: np.ndarray) -> None:
    """BackgroundMismatchError when the clean plate (BGR uint8 at the video's size) is not of
    this video's scene: another scene or camera, or grey against colour (such a plate makes
    every frame one whole-image "person", or nobody at all)."""
    size = _scaled_size(source.width, source.height, 320)
    small = cv2.resize(plate, size, interpolation=cv2.INTER_AREA)
    frames = source.sample_frames(PLATE_CHECK_FRAMES, size=size)
    if not frames:
        raise nothing_decodes(source)
    # The video's colour from the samples' median, where a passing person (a red top on a grey
    # room) is gone.
    plate_grey, video_grey = colourless(small), colourless(median_background(frames))
    if plate_grey != video_grey:
        raise BackgroundMismatchError(
            f"the background image is {'grey' if plate_grey else 'in colour'} and the video "
            f"{'grey' if video_grey else 'in colour'}: not a clean plate of this video")
    meter = GainMeter(small)
    changed = []
    for frame in frames:
        gain = meter(frame)
        if np.all(gain > 0):
            frame = undo_gain(frame, gain)
        differs = (cv2.absdiff(frame, small).max(axis=2) > PLATE_TOLERANCE).astype(np.float32)
        cells = cv2.resize(differs, (8, 8), interpolation=cv2.INTER_AREA)
        changed.append(float((cells > 0.1).mean()))
    if np.median(changed) > PLATE_MAX_CELLS:
        raise BackgroundMismatchError(
            f"the background image differs from the video all over ({np.median(changed):.0%} "
            f"of the image's regions, median over {len(frames)} frames): not a clean plate of "
            f"this scene and camera")
