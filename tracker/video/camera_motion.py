"""Is the camera moving (background subtraction needs a still one)? A whole-image shift between
frames is their phase correlation's peak where it aligns the scene (people cover a minority of
it); at least MIN_SHIFT of the width is camera motion. :func:`camera_moves` compares a clip's
samples in turn, tracker.video.segmenter.CameraMotionMeter each frame with an earlier one."""
from __future__ import annotations

import functools

import cv2
import numpy as np

from tracker.video.area_shrink import shrink

#: Width (px) of the grey copies compared: a 160x120 phase correlation costs about 0.3 ms.
ANALYSIS_WIDTH = 160
#: Camera motion: a shift of at least this fraction of the width (a still scene's: ~0.2 px).
MIN_SHIFT = 0.01
#: A grey copy varying less than this (grey levels, standard deviation) has nothing to align
#: (black, a fade, a covered lens) and is left out, else frames after a fade-in all "moved".
FLAT_STD = 2.0
#: The runner-up peak is looked for at least this far (px) from no shift.
OFF_ZERO_PX = 2
#: ... and only where the median cell of a GRID x GRID division changes by more than this (grey
#: levels, mean absolute difference): a pan changes most cells, people a few (figures: code_notes).
CHANGED_LEVEL = 2.0
#: A shift explains a cell of a GRID x GRID division when it brings the cell's mean absolute
#: difference under this share of the unshifted one's (and fails it above it by this share).
ALIGNED_SHARE = 0.8
GRID = 3


def small_grey(frame: np.ndarray, width: int = ANALYSIS_WIDTH) -> np.ndarray:
    """A BGR uint8 (H, W, 3) or grey (H, W) frame as float32 grey (h, w), at most ``width`` px."""
    grey = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    height, full = grey.shape
    if full > width:
        grey = shrink(grey, (width, max(1, round(height * width / full))))
    return grey.astype(np.float32)


def frame_shift(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """(shift of ``b`` against ``a`` as a fraction of the width (>= 0), peak response 0..1) of
    two :func:`small_grey` images of one size: the phase correlation's peak if it aligns the
    scene (:func:`_explains`); with no shift but a changed scene, the highest peak off zero if
    it does (a subject the camera follows can hold the peak at 0)."""
    window = _hanning(a.shape)
    # Copies: OpenCV 4.11's phaseCorrelate multiplies its inputs by the window in place.
    (dx, dy), response = cv2.phaseCorrelate(a.copy(), b.copy(), window)
    shift = float(np.hypot(dx, dy)) / a.shape[1]
    if shift > 0 and not _explains(a, b, dx, dy):
        shift = 0.0
    if shift * a.shape[1] < OFF_ZERO_PX and \
            float(np.median(_cell_means(np.abs(a - b)))) > CHANGED_LEVEL:    # the scene changed
        ox, oy = _off_zero_peak(a, b, window)
        if _explains(a, b, ox, oy):
            return float(np.hypot(ox, oy)) / a.shape[1], float(response)
    return shift, float(response)


def _off_zero_peak(a: np.ndarray, b: np.ndarray, window: np.ndarray) -> tuple[float, float]:
    """(dx, dy) whole px, as phaseCorrelate's: the highest peak of the windowed phase
    correlation of ``a`` and ``b`` at least OFF_ZERO_PX from no shift."""
    fa, fb = np.fft.rfft2(a * window), np.fft.rfft2(b * window)
    cross = fb * np.conj(fa)
    surface = np.fft.fftshift(np.fft.irfft2(cross / np.maximum(np.abs(cross), 1e-12),
                                            s=a.shape))
    cy, cx = a.shape[0] // 2, a.shape[1] // 2
    r = OFF_ZERO_PX
    surface[cy - r + 1:cy + r, cx - r + 1:cx + r] = -np.inf
    iy, ix = np.unravel_index(int(np.argmax(surface)), surface.shape)
    return float(ix - cx), float(iy - cy)


def _explains(a: np.ndarray, b: np.ndarray, dx: float, dy: float) -> bool:
    """Whether ``b`` moved back by (dx, dy) px matches ``a`` better in more cells of their common
    part than worse (a pan moves every textured cell alike, a person only their own)."""
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


@functools.lru_cache(maxsize=None)
def _hanning(shape: tuple[int, int]) -> np.ndarray:
    """OpenCV's Hanning window (float32 (h, w)) for images of ``shape``, made once per shape."""
    return cv2.createHanningWindow((shape[1], shape[0]), cv2.CV_32F)


def flat(grey: np.ndarray) -> bool:
    """Whether a :func:`small_grey` image has too little texture to align (:data:`FLAT_STD`)."""
    return float(grey.std()) < FLAT_STD


def camera_moves(frames) -> bool:
    """Whether frames spread over a clip (list or (N, H, W, 3) BGR uint8, in time order) were
    taken by a moving camera: over half of the consecutive non-flat pairs moved (MIN_SHIFT)."""
    greys = [g for g in (small_grey(f) for f in frames) if not flat(g)]
    if len(greys) < 2:
        return False
    moves = [frame_shift(a, b)[0] >= MIN_SHIFT for a, b in zip(greys, greys[1:])]
    return sum(moves) > len(moves) / 2
