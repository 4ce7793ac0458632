"""Is the camera moving? Global motion between frames, by phase correlation on small grey copies.

Background subtraction needs a still camera: when the camera pans, tilts or shakes, every pixel
changes and the background model's "foreground" is the scene, not the people. A whole-image
shift between two frames shows as the peak of their phase correlation (OpenCV's
``phaseCorrelate``, on grey copies ANALYSIS_WIDTH px wide with a Hanning window against the
borders): people cover a minority of the image and move on their own, so the peak is the
background's, and where it is not (a person crossing a faintly textured scene), moving the
whole image by it misaligns the scene, and it is dropped (:func:`frame_shift`). A shift of at
least MIN_SHIFT of the frame's width counts as camera motion.
Per frame (:class:`CameraMotionMeter`) a frame is compared with the one STEP_FRAMES earlier, so a
slow pan adds up to a measurable shift; over a clip's sampled frames (:func:`camera_moves`) the
samples are compared one with the next.
"""
from __future__ import annotations

from collections import deque

import cv2
import numpy as np

from tracker.video.area_shrink import shrink

#: Width (px) of the grey copies compared: a 160x120 phase correlation costs about 0.3 ms.
ANALYSIS_WIDTH = 160
#: A shift between two frames of at least this fraction of the frame width is camera motion
#: (1.6 px at ANALYSIS_WIDTH; phase correlation of a still scene stays within about 0.2 px).
MIN_SHIFT = 0.01
#: The per-frame meter compares a frame with the one this many frames earlier.
STEP_FRAMES = 5
#: Consecutive comparisons that must show motion before the meter says the camera moves.
MOVING_RUN = 3
#: A frame whose grey copy varies less than this (grey levels, standard deviation) shows nothing
#: to align (black, a fade, a covered lens): it is left out of the comparisons, else the first
#: frames after a fade-in all "moved" against the black ones.
FLAT_STD = 2.0


def small_grey(frame: np.ndarray, width: int = ANALYSIS_WIDTH) -> np.ndarray:
    """A BGR uint8 (H, W, 3) or grey (H, W) frame as float32 grey (h, w) ``width`` px wide
    (never enlarged), for :func:`frame_shift`."""
    grey = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    height, full = grey.shape
    if full > width:
        grey = shrink(grey, (width, max(1, round(height * width / full))))
    return grey.astype(np.float32)


def frame_shift(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """(shift of ``b`` against ``a`` as a fraction of the width (>= 0), peak response 0..1) of
    two :func:`small_grey` images of one size. The shift is the phase correlation's peak, kept
    only where it explains the two images better than no shift at all (:func:`_explains`): a
    person moving in front of a still, faintly textured scene can make the peak theirs, but
    moving the whole image by it misaligns the scene. Where the peak is at (or is dropped to)
    no shift, the highest peak away from it is tried the same way: a subject the camera
    follows stays put in the middle of the view, where the window weighs most, and can hold
    the peak at no shift while the scene pans behind (a figure of 4 % of the view did).
    Otherwise the shift is 0."""
    window = _hanning(a.shape)
    # Copies: OpenCV 4.11's phaseCorrelate multiplies its inputs by the window in place.
    (dx, dy), response = cv2.phaseCorrelate(a.copy(), b.copy(), window)
    shift = float(np.hypot(dx, dy)) / a.shape[1]
    if shift > 0 and not _explains(a, b, dx, dy):
        shift = 0.0
    if shift * a.shape[1] < OFF_ZERO_PX and _scene_changed(a, b):
        # A subject the camera follows stays put and can hold the peak at no shift.
        ox, oy = _off_zero_peak(a, b, window)
        if _explains(a, b, ox, oy):
            return float(np.hypot(ox, oy)) / a.shape[1], float(response)
    return shift, float(response)


#: The runner-up peak is looked for at least this far (px) from no shift.
OFF_ZERO_PX = 2
#: ... and only where the median cell of a GRID x GRID division of the two frames differs by
#: more than this (grey levels, mean absolute difference): a still camera's frames change in
#: the people's cells only (the median cell: 0.3-2.2 levels on the shipped sample, the Pose2Sim
#: views and the panning renders' static twins, up to 5.3 on swings cam01), a pan in most
#: (6-7 on the panning renders, 13-16 on the tests' synthetic one). A saving only: the
#: runner-up's shift must still align the scene (:func:`_explains`).
CHANGED_LEVEL = 2.0


def _scene_changed(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether more than half of the cells of two :func:`small_grey` images changed by over
    CHANGED_LEVEL grey levels (mean absolute difference)."""
    return float(np.median(_cell_means(np.abs(a - b)))) > CHANGED_LEVEL


def _off_zero_peak(a: np.ndarray, b: np.ndarray, window: np.ndarray) -> tuple[float, float]:
    """(dx, dy) px, as phaseCorrelate's: the highest peak of the windowed phase correlation
    of ``a`` and ``b`` at least OFF_ZERO_PX from no shift (whole pixels)."""
    fa, fb = np.fft.rfft2(a * window), np.fft.rfft2(b * window)
    cross = fb * np.conj(fa)
    surface = np.fft.fftshift(np.fft.irfft2(cross / np.maximum(np.abs(cross), 1e-12),
                                            s=a.shape))
    cy, cx = a.shape[0] // 2, a.shape[1] // 2
    r = OFF_ZERO_PX
    surface[cy - r + 1:cy + r, cx - r + 1:cx + r] = -np.inf
    iy, ix = np.unravel_index(int(np.argmax(surface)), surface.shape)
    return float(ix - cx), float(iy - cy)


#: A shift explains two frames in a cell of a GRID x GRID division of the image when it brings
#: the cell's mean absolute difference to under this share of the unshifted frames' (and
#: fails to where it raises it above the unshifted's over this share).
ALIGNED_SHARE = 0.8
GRID = 3


def _explains(a: np.ndarray, b: np.ndarray, dx: float, dy: float) -> bool:
    """Whether ``b`` moved back by (dx, dy) px matches ``a`` better than ``b`` as it is: in
    more cells of a GRID x GRID division of their common part than it matches worse. A moving
    camera moves every textured cell the same way (flat cells, a blank wall or a mat, change
    neither way); a person moving across a still scene improves only their own cells and
    misaligns the scene's texture in the others. (One statistic over the whole image failed
    both ways: a median stayed at the noise level over flat surfaces and missed a pan, a mean
    followed a person across a blank wall.)"""
    height, width = a.shape
    mx, my = int(np.ceil(abs(dx))) + 1, int(np.ceil(abs(dy))) + 1
    if 2 * mx >= width or 2 * my >= height:
        return True                 # nothing left to compare: the view changed wholesale
    back = cv2.warpAffine(b, np.float32([[1, 0, -dx], [0, 1, -dy]]), (width, height))
    inner = (slice(my, height - my), slice(mx, width - mx))
    still = _cell_means(np.abs(a[inner] - b[inner]))
    moved_back = _cell_means(np.abs(a[inner] - back[inner]))
    better = int(np.count_nonzero(moved_back < ALIGNED_SHARE * still))
    worse = int(np.count_nonzero(ALIGNED_SHARE * moved_back > still))
    return better > worse


def _cell_means(image: np.ndarray) -> np.ndarray:
    """Means (GRID * GRID,) of the cells of a GRID x GRID division of ``image`` (h, w)."""
    rows = np.array_split(np.arange(image.shape[0]), GRID)
    cols = np.array_split(np.arange(image.shape[1]), GRID)
    return np.array([image[r[0]:r[-1] + 1, c[0]:c[-1] + 1].mean() for r in rows for c in cols])


_WINDOWS: dict[tuple[int, int], np.ndarray] = {}


def _hanning(shape: tuple[int, int]) -> np.ndarray:
    """OpenCV's Hanning window (float32 (h, w)) for images of ``shape``, made once per shape."""
    if shape not in _WINDOWS:
        _WINDOWS[shape] = cv2.createHanningWindow((shape[1], shape[0]), cv2.CV_32F)
    return _WINDOWS[shape]


def flat(grey: np.ndarray) -> bool:
    """Whether a :func:`small_grey` image has too little texture to align (:data:`FLAT_STD`)."""
    return float(grey.std()) < FLAT_STD


def moved(shift: float, min_shift: float = MIN_SHIFT) -> bool:
    """Whether a :func:`frame_shift` shift (a fraction of the width) is camera motion. A weak
    peak alone is not: two frames of a still camera on a blank wall have none either."""
    return shift >= min_shift


def camera_moves(frames, min_shift: float = MIN_SHIFT) -> bool:
    """Whether frames spread over a clip (a list or (N, H, W, 3) BGR uint8, in time order, e.g.
    ``VideoSource.sample_frames``) were taken by a moving camera: more than half of the pairs
    of consecutive samples moved (:func:`moved`), flat samples (:func:`flat`) left out. A still
    camera's samples all line up, people or not; fewer than two frames say nothing (False)."""
    greys = [g for g in (small_grey(f) for f in frames) if not flat(g)]
    if len(greys) < 2:
        return False
    moves = [moved(frame_shift(a, b)[0], min_shift) for a, b in zip(greys, greys[1:])]
    return sum(moves) > len(moves) / 2


class CameraMotionMeter:
    """Per-frame camera motion: call it with each frame (BGR uint8 (H, W, 3)) in order; it
    returns whether the camera moves, i.e. the last ``run`` comparisons of a frame with the
    one ``step`` frames earlier all moved (:func:`moved`); flat frames (:func:`flat`) are skipped.
    :attr:`moving_since` is the frame
    count at the first such answer (None while the camera has stayed still)."""

    def __init__(self, step: int = STEP_FRAMES, run: int = MOVING_RUN,
                 min_shift: float = MIN_SHIFT):
        if step < 1 or run < 1:
            raise ValueError(f"step={step} and run={run} must be at least 1")
        self.step, self.run = step, run
        self.min_shift = min_shift
        self._recent: deque = deque(maxlen=step + 1)
        self._streak = 0
        self.frames = 0
        self.moving_since: int | None = None

    def __call__(self, frame: np.ndarray) -> bool:
        grey = small_grey(frame)
        self.frames += 1
        if flat(grey):                      # nothing to compare: the answer stays as it was
            return self._streak >= self.run
        if self._recent and self._recent[0].shape != grey.shape:
            self._recent.clear()
        self._recent.append(grey)
        if len(self._recent) <= self.step:
            return False
        shift, _ = frame_shift(self._recent[0], grey)
        self._streak = self._streak + 1 if moved(shift, self.min_shift) else 0
        moving = self._streak >= self.run
        if moving and self.moving_since is None:
            self.moving_since = self.frames
        return moving
