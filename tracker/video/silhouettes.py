"""Frames to person silhouettes: background subtraction (MOG2, on a copy ``working_width`` px
wide), mask cleaning, one mask per person scaled back to the frame. Per frame: OpenCV or numpy
on the image or its foreground's box; Python loops run over people only."""
from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

from regressor.errors import SilhouettePoseError
from tracker.video.area_shrink import shrink
from tracker.video.background import (MIN_GAIN_CHANGE, ClipBackground, GainMeter, clean_plate,
                                      clip_background, row_medians, undo_gain)
from tracker.video.noise_floor import FOREGROUND_LEVEL as _FOREGROUND_LEVEL, choose_var_min

_SHADOW_LEVEL = 127              # MOG2's mark for shadow (foreground: _FOREGROUND_LEVEL)
# A gain beyond this in a channel (black, a flash, a cut) is no one: it made a whole-image blob.
_MAX_GAIN_FACTOR = 4.0
#: Components larger than this fraction of the image are a change of the whole scene, not
#: people (a standing person filling a portrait frame's height covers about 15-35 %).
DEFAULT_MAX_AREA_FRACTION = 0.5
#: Smaller components (fraction of the image) are clutter; a 55 px walker at 640x480 passes.
DEFAULT_MIN_AREA_FRACTION = 0.0015
# OpenCV MOG2's default cap on a pixel's variance (grey levels squared): no floor above it.
_MOG2_VAR_MAX = 75.0
_VAR_THRESHOLD = 16.0       # MOG2's: squared Mahalanobis distance beyond which is foreground
#: MOG2's weight share that is background: a still person joins it after ln(ratio) /
#: ln(1 - 1/history) frames (~180 at 0.7 and history 500, ~50 at MOG2's 0.9).
_BACKGROUND_RATIO = 0.7
_SQUARE_3 = np.ones((3, 3), np.uint8)


class ExtractionError(SilhouettePoseError, ValueError):
    """Bad settings or frames for silhouette extraction; one-line message naming the problem."""


@dataclass(frozen=True)
class PersonMask:
    """One person's silhouette in frame pixel coordinates: ``mask`` (h, w) bool crop, True on
    the person; ``bbox`` (x, y, w, h) px of the crop; ``centroid`` (x, y) px of the mask's centre
    of mass; ``area`` foreground px; ``colour`` :func:`colour_histogram` (COLOUR_BINS,) of the
    frame inside the silhouette, or None when not measured."""

    mask: np.ndarray
    bbox: tuple[int, int, int, int]
    centroid: tuple[float, float]
    area: int
    colour: np.ndarray | None = None


#: Bins over hue, saturation and value (OpenCV's HSV): hue and saturation tell clothes apart
#: under the same light, value tells black from white.
COLOUR_BINS_HSV = (8, 4, 4)
COLOUR_BINS = int(np.prod(COLOUR_BINS_HSV))


def colour_histogram(image: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """HSV histogram (COLOUR_BINS,) float32 summing to 1 (zeros for an empty mask) of ``image``
    (BGR uint8 (h, w, 3)) where ``mask`` (uint8 (h, w)) is set: tells people apart."""
    hsv = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
    hist = cv2.calcHist([hsv], [0, 1, 2], mask, list(COLOUR_BINS_HSV), [0, 180, 0, 256, 0, 256])
    total = float(hist.sum())
    return (hist.ravel() / total if total else hist.ravel()).astype(np.float32)


class BackgroundSubtractor:
    """MOG2 background model on a frame shrunk to ``working_width`` px, shadows removed.
    ``history``: frames remembered; after ``warmup_frames`` only learned from, the model learns
    at 1/history (MOG2's own 1/frames seen swallows a still person within a second);
    ``normalise_brightness``: undo global gain changes (:meth:`subtract`); ``var_min``: MOG2's
    variance floor (grey levels squared, tracker.video.noise_floor)."""

    def __init__(self, working_width: int = 320, history: int = 500, detect_shadows: bool = True,
                 warmup_frames: int = 15, normalise_brightness: bool = True, var_min: float = 4.0):
        if working_width < 16:
            raise ExtractionError(f"working_width={working_width} must be at least 16 px")
        if history < 1 or warmup_frames < 0:
            raise ExtractionError(f"history={history} must be >= 1 and warmup_frames="
                                  f"{warmup_frames} >= 0")
        _check_var_min(var_min)
        self.working_width = working_width
        self.warmup_frames = warmup_frames
        self.learning_rate = 1.0 / history
        self.normalise_brightness = normalise_brightness
        #: Background at working size the brightness gain is measured against (set by prime).
        self.reference: np.ndarray | None = None
        self.frames_seen = 0
        self._frame_size: tuple[int, int] | None = None
        self._mog2_options = dict(history=history, varThreshold=_VAR_THRESHOLD,
                                  detectShadows=detect_shadows)
        self.var_min = float(var_min)
        self._model = self.new_model(self.var_min)
        # Learning rates of prime's lessons of the reference not yet given to the model: given
        # on its first use, never when retune replaces it first (a floor chosen for the clip).
        self._lessons: list[float] = []

    def new_model(self, var_min: float):
        """A fresh OpenCV MOG2 with these settings and variance floor ``var_min``."""
        model = cv2.createBackgroundSubtractorMOG2(**self._mog2_options)
        model.setBackgroundRatio(_BACKGROUND_RATIO)
        model.setVarMin(float(var_min))
        # A new Gaussian starts at varInit (15 by default), which must not be below the floor.
        model.setVarInit(max(model.getVarInit(), float(var_min)))
        return model

    def primed_model(self, var_min: float):
        """A :meth:`new_model` that has learned :attr:`reference` as :meth:`prime` teaches it."""
        if self.reference is None:
            raise ExtractionError("a primed model needs prime() first")
        model = self.new_model(var_min)
        for _ in range(max(self.warmup_frames, 1)):
            model.apply(self.reference, learningRate=-1.0)
        return model

    def retune(self, var_min: float) -> None:
        """Rebuild the model with variance floor ``var_min`` and re-learn :attr:`reference`."""
        if self.reference is None:
            raise ExtractionError("retune needs prime() first")
        _check_var_min(var_min)
        self.var_min = float(var_min)
        self._model = self.primed_model(self.var_min)
        self._lessons = []

    @property
    def ready(self) -> bool:
        """True once the warm-up frames have been seen."""
        return self.frames_seen >= self.warmup_frames

    def working_size(self, width: int, height: int) -> tuple[int, int]:
        """(width, height) px of the image the model works on for a frame of width x height."""
        if width <= self.working_width:
            return width, height
        return self.working_width, max(1, round(height * self.working_width / width))

    def prime(self, background: np.ndarray, frame_size: tuple[int, int] | None = None) -> None:
        """Learn the empty scene (BGR uint8 (H, W, 3)) at MOG2's start-up rate until
        :attr:`ready` (no warm-up "ghost" of a person). ``frame_size``: None when ``background``
        has the frames' size; else the frames' (width, height) px, ``background`` being at
        :meth:`working_size` already (a median of shrunk frames: rescaling would blur it)."""
        if background.ndim != 3 or background.shape[2] != 3 or background.dtype != np.uint8:
            raise ExtractionError(f"background must be BGR uint8 (H, W, 3), got "
                                  f"{background.dtype} {background.shape}")
        given = (background.shape[1], background.shape[0])
        if frame_size is None:
            frame_size = given
            work = self.working_size(*given)
            small = background if work == given else shrink(background, work)
        else:
            frame_size = (int(frame_size[0]), int(frame_size[1]))
            if given != self.working_size(*frame_size):
                raise ExtractionError(f"a background for {frame_size[0]}x{frame_size[1]} frames "
                                      f"must be {self.working_size(*frame_size)} px at working "
                                      f"size, got {given[0]}x{given[1]}")
            small = background
        self._check_frame_size(frame_size)
        self._learn_lessons()
        for _ in range(max(self.warmup_frames - self.frames_seen, 1)):
            self._lessons.append(-1.0 if not self.ready else self.learning_rate)
            self.frames_seen += 1
        self.reference = small.copy()
        self._gain = GainMeter(self.reference)

    def _learn_lessons(self) -> None:
        """Give the model prime's lessons of :attr:`reference` still owed (see __init__)."""
        for rate in self._lessons:
            self._model.apply(self.reference, learningRate=rate)
        self._lessons = []

    def _check_frame_size(self, size: tuple[int, int]) -> None:
        """Remember the frames' (width, height) px on first use; refuse any other size later."""
        if self._frame_size is None:
            self._frame_size = size
        elif size != self._frame_size:
            raise ExtractionError(f"frame size changed from {self._frame_size[0]}x"
                                  f"{self._frame_size[1]} to {size[0]}x{size[1]}")

    def subtract(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Update the model with ``frame`` (BGR uint8 (H, W, 3)); returns (the frame at
        :meth:`working_size`, BGR uint8 (h, w, 3); MOG2's mask uint8 (h, w): 255 foreground,
        127 shadow, 0 background). Once primed, a gain over the reference beyond MIN_GAIN_CHANGE
        is undone; beyond _MAX_GAIN_FACTOR the mask is empty and the frame not learned."""
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            raise ExtractionError(f"frame must be BGR uint8 (H, W, 3), got {frame.dtype} "
                                  f"{frame.shape}")
        size = (frame.shape[1], frame.shape[0])
        self._check_frame_size(size)
        work = self.working_size(*size)
        small = frame if work == size else shrink(frame, work)
        saturated = None
        if self.reference is not None and self.normalise_brightness:
            gain = self._gain(small)
            low, high = float(gain.min()), float(gain.max())
            if not (low >= 1 / _MAX_GAIN_FACTOR and high <= _MAX_GAIN_FACTOR):
                self.frames_seen += 1
                return small, np.zeros(small.shape[:2], np.uint8)
            if max(1.0 - low, high - 1.0) > MIN_GAIN_CHANGE:
                # Where brighter light clips the background it cannot be undone: no blob there.
                expected = cv2.multiply(self.reference, tuple(float(g) for g in gain) + (0.0,))
                saturated = (expected.max(axis=2) >= 250) & (small.max(axis=2) >= 250)
                small = undo_gain(small, gain)
        rate = -1.0 if not self.ready else self.learning_rate
        self._learn_lessons()
        raw = self._model.apply(small, learningRate=rate)
        if saturated is not None:
            raw[saturated] = 0
        self.frames_seen += 1
        return small, raw


def _check_var_min(var_min: float) -> None:
    if not (np.isfinite(var_min) and 0.0 < var_min <= _MOG2_VAR_MAX):
        raise ExtractionError(f"var_min={var_min} must be in (0, {_MOG2_VAR_MAX:g}] grey levels "
                              "squared")


def median_background(frames: list[np.ndarray]) -> np.ndarray:
    """Per-pixel median of frames (each BGR uint8 (H, W, 3)) -> BGR uint8 (H, W, 3): the empty
    scene wherever no one stood still in half of them."""
    if not frames:
        raise ExtractionError("median_background needs at least one frame")
    shapes = {f.shape for f in frames}
    if len(shapes) != 1:
        raise ExtractionError(f"median_background frames differ in shape: {sorted(shapes)}")
    return np.median(np.stack(frames), axis=0).astype(np.uint8)


def clean_mask(mask: np.ndarray, open_px: int = 3, close_px: int = 5,
               restore_px: int = 1) -> np.ndarray:
    """A foreground mask (uint8 (h, w), 255 = foreground) without specks and small gaps: an
    elliptical opening of ``open_px`` and closing of ``close_px`` px (<= 1 skips one); what the
    opening shaved within ``restore_px`` px of what it kept (toes, wrists) is put back."""
    cleaned = mask
    if open_px > 1:
        opened = cv2.morphologyEx(cleaned, cv2.MORPH_OPEN, _ellipse(open_px))
        if restore_px > 0:
            near = cv2.dilate(opened, _SQUARE_3, iterations=restore_px)
            opened = cv2.bitwise_or(opened, cv2.bitwise_and(near, cleaned))
        cleaned = opened
    if close_px > 1:
        cleaned = cv2.morphologyEx(cleaned, cv2.MORPH_CLOSE, _ellipse(close_px))
    return cleaned


@functools.lru_cache(maxsize=16)
def _ellipse(size: int) -> np.ndarray:
    """OpenCV's elliptical structuring element of size x size px (uint8), made once."""
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))


def person_masks(mask: np.ndarray, frame_size: tuple[int, int],
                 min_area_fraction: float = DEFAULT_MIN_AREA_FRACTION,
                 max_hole_fraction: float = 0.002, merge_fragments: bool = True,
                 max_fragment_area: float = 0.15,
                 max_area_fraction: float = DEFAULT_MAX_AREA_FRACTION,
                 image: np.ndarray | None = None) -> list[PersonMask]:
    """One :class:`PersonMask` per 8-connected component of a cleaned mask (uint8 (h, w),
    255 = foreground) scaled to ``frame_size`` (width, height) px, largest first. Components
    outside [min, max]_area_fraction of the image go; holes up to ``max_hole_fraction`` are
    filled (not those between an arm and the torso); ``merge_fragments`` joins pieces of one
    person (tracker.video.fragments); ``image`` (BGR uint8 (h, w, 3)) gives the colours."""
    height, width = mask.shape
    image_area = float(height * width)
    box = _padded_box(mask, 0)
    if box is None:
        return []
    # Contours of outer boundaries and their holes, filled, reproduce each component exactly
    # and cost far less than connectedComponentsWithStats; traced in the foreground's box only.
    contours, hierarchy = cv2.findContours(mask[box], cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE,
                                           offset=(box[1].start, box[0].start))
    parents = hierarchy[0][:, 3]
    areas = np.array([cv2.contourArea(c) for c in contours])
    # contourArea undercounts by about half the perimeter: enough to gate clutter.
    outers = np.flatnonzero((parents == -1) & (areas >= min_area_fraction * image_area)
                            & (areas <= max_area_fraction * image_area))
    big_holes = np.flatnonzero((parents != -1) & (areas > max_hole_fraction * image_area))
    rects = np.array([cv2.boundingRect(contours[o]) for o in outers]).reshape(-1, 4)
    people = []
    groups = [[i] for i in range(len(rects))]
    if merge_fragments and len(rects) > 1:
        from tracker.video.fragments import fragment_groups     # only with pieces to join
        groups = fragment_groups(rects, areas[outers], max_fragment_area)
    for group in groups:
        members = [int(outers[g]) for g in group]
        holes = [contours[h] for h in big_holes if parents[h] in members]
        people.append(_person_from_contours(contours, members, holes, mask.shape, frame_size,
                                            image))
    return sorted((p for p in people if p is not None), key=lambda p: -p.area)


def _person_from_contours(contours, members: list[int], holes: list[np.ndarray],
                          shape: tuple[int, int], frame_size: tuple[int, int],
                          image: np.ndarray | None = None) -> PersonMask | None:
    """One person's pieces rasterized, joined across their gaps, minus their kept holes, its
    colour measured in ``image`` (at the mask's size), scaled to frame px."""
    height, width = shape
    frame_width, frame_height = frame_size
    sx, sy = frame_width / width, frame_height / height
    pts = np.vstack([contours[m].reshape(-1, 2) for m in members])
    x, y, w, h = cv2.boundingRect(pts)
    crop = np.zeros((h, w), np.uint8)
    for m in members:
        cv2.drawContours(crop, contours, m, 255, cv2.FILLED, offset=(-x, -y))
    if holes:
        # A hole's contour runs through the foreground around it: erase inside, restore rim.
        cv2.drawContours(crop, holes, -1, 0, cv2.FILLED, offset=(-x, -y))
        cv2.drawContours(crop, holes, -1, 255, 1, offset=(-x, -y))
    if len(members) > 1:
        from tracker.video.fragments import bridge_vertical_gaps
        crop = bridge_vertical_gaps(crop, [cv2.boundingRect(contours[m]) for m in members])
    colour = None if image is None else colour_histogram(image[y:y + h, x:x + w], crop)
    x0, y0 = int(round(x * sx)), int(round(y * sy))
    x1 = min(frame_width, int(round((x + w) * sx)))
    y1 = min(frame_height, int(round((y + h) * sy)))
    if (x1 - x0, y1 - y0) != (w, h):
        crop = cv2.resize(crop, (x1 - x0, y1 - y0), interpolation=cv2.INTER_LINEAR)
        _, crop = cv2.threshold(crop, 127, 255, cv2.THRESH_BINARY)
    moments = cv2.moments(crop, binaryImage=True)
    if moments["m00"] == 0:
        return None
    centroid = (x0 + moments["m10"] / moments["m00"], y0 + moments["m01"] / moments["m00"])
    return PersonMask(crop > 0, (x0, y0, x1 - x0, y1 - y0), centroid, int(moments["m00"]),
                      colour)


def enclosed_shadow(foreground: np.ndarray, shadow: np.ndarray) -> np.ndarray:
    """uint8 (h, w), 255 on the ``shadow`` pixels (bool (h, w)) with ``foreground`` (bool
    (h, w)) above and below in their column: dark clothing inside a body, not a shadow cast on
    the ground (nothing of the body below it). Computed in the shadow's box only."""
    out = np.zeros(shadow.shape, np.uint8)
    shadow_cols = np.flatnonzero(shadow.any(axis=0))
    if not len(shadow_cols):
        return out
    shadow_rows = np.flatnonzero(shadow.any(axis=1))
    c0, c1 = shadow_cols[0], shadow_cols[-1] + 1
    r0, r1 = shadow_rows[0], shadow_rows[-1] + 1
    height = foreground.shape[0]
    fg = foreground[:, c0:c1]
    top = np.where(fg.any(axis=0), fg.argmax(axis=0), height)                  # (w,)
    bottom = height - 1 - fg[::-1].argmax(axis=0)                              # (w,)
    rows = np.arange(r0, r1)[:, None]
    out[r0:r1, c0:c1] = (shadow[r0:r1, c0:c1] & (rows > top) & (rows < bottom)) * np.uint8(255)
    return out


def drop_lighting_blobs(mask: np.ndarray, frame: np.ndarray, background: np.ndarray,
                        min_correlation: float = 0.85, max_ratio_spread: float = 0.08,
                        min_area: int = 0) -> np.ndarray:
    """A copy of ``mask`` (uint8 (h, w), 255 = foreground) without blobs (of ``min_area`` px or
    more) where the frame is the background under other light (both BGR uint8 (h, w, 3)): grey
    levels correlating above ``min_correlation``, or log(frame / background)'s median absolute
    deviation under ``max_ratio_spread``."""
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    out = mask.copy()
    for contour in contours:
        x, y, w, h = cv2.boundingRect(contour)
        if w * h < max(min_area, 16):
            continue
        blob = np.zeros((h, w), np.uint8)
        cv2.drawContours(blob, [contour], -1, 255, cv2.FILLED, offset=(-x, -y))
        inside = np.flatnonzero(blob)
        f = frame[y:y + h, x:x + w].reshape(-1, 3)[inside]          # (n, 3) uint8
        b = background[y:y + h, x:x + w].reshape(-1, 3)[inside]
        if _relit(f, b, min_correlation, max_ratio_spread):
            out[y:y + h, x:x + w][blob > 0] = 0
    return out


def _relit(frame: np.ndarray, background: np.ndarray, min_correlation: float,
           max_ratio_spread: float) -> bool:
    """Whether a blob's pixels (frame, background BGR uint8 (n, 3)) pass either test of
    :func:`drop_lighting_blobs`; the dearer ratio test only if the correlation fails."""
    f = frame.astype(np.float32)
    f += 4.0
    b = background.astype(np.float32)
    b += 4.0
    third = np.full(3, 1 / 3, np.float32)
    fg, bg = f @ third, b @ third                   # grey levels (n,), then their deviations
    fg -= fg.mean()
    bg -= bg.mean()
    denominator = float(np.sqrt(np.dot(fg, fg) * np.dot(bg, bg)))
    if denominator > 0 and float(np.dot(fg, bg)) / denominator > min_correlation:
        return True
    log_ratio = np.log(np.divide(f, b, out=f), out=f).ravel()
    log_ratio -= row_medians(log_ratio[None])[0]        # np.median's, by a partial sort
    return float(row_medians(np.abs(log_ratio, out=log_ratio)[None])[0]) < max_ratio_spread


class SilhouetteExtractor:
    """Frame -> list of :class:`PersonMask`: subtraction, cleaning and splitting in one call.
    Keyword arguments go to :class:`BackgroundSubtractor`; the others turn on or set
    :func:`clean_mask`, :func:`person_masks`, :func:`enclosed_shadow`, :func:`drop_lighting_blobs`,
    tracker.video.zone.ZoneRefiner (``refine``) and tracker.video.noise_floor.choose_var_min
    (``adapt_noise_floor``; off with an explicit ``var_min``)."""

    def __init__(self, open_px: int = 3, close_px: int = 5, restore_px: int = 1,
                 min_area_fraction: float = DEFAULT_MIN_AREA_FRACTION,
                 max_hole_fraction: float = 0.002,
                 max_fragment_area: float = 0.15, keep_enclosed_shadow: bool = True,
                 drop_lighting: bool = True, refine: bool = True,
                 refine_relearn_every: int = 3, adapt_noise_floor: bool = True,
                 trust_zone_foreground: bool = True, **subtractor_options):
        self.subtractor = BackgroundSubtractor(**subtractor_options)
        self.adapt_noise_floor = adapt_noise_floor and "var_min" not in subtractor_options
        self.open_px, self.close_px, self.restore_px = open_px, close_px, restore_px
        self.min_area_fraction, self.max_hole_fraction, self.max_fragment_area = \
            min_area_fraction, max_hole_fraction, max_fragment_area
        self.keep_enclosed_shadow, self.drop_lighting, self.refine = \
            keep_enclosed_shadow, drop_lighting, refine
        if refine_relearn_every < 1:
            raise ExtractionError(f"refine_relearn_every={refine_relearn_every} must be >= 1")
        self.refine_relearn_every = refine_relearn_every
        self.trust_zone_foreground = trust_zone_foreground
        self.refiner = None         # a tracker.video.zone.ZoneRefiner, made when needed
        self.background: ClipBackground | None = None

    def prime(self, background, frame_size: tuple[int, int] | None = None) -> None:
        """Learn the scene from an empty-scene image (BGR uint8 (H, W, 3), trusted everywhere;
        ``frame_size`` as in :meth:`BackgroundSubtractor.prime`) or from frames spread over the
        clip (list or (N, H, W, 3)): tracker.video.background.clip_background."""
        if isinstance(background, np.ndarray) and background.ndim == 3:
            self.subtractor.prime(background, frame_size)
            self.background = clean_plate(self.subtractor.reference)
            self.refiner = None
            return
        frames = list(background)
        if not frames:
            raise ExtractionError("prime needs a background image or at least one frame")
        small = self._working_frames(frames)
        estimate = clip_background(small)
        self.subtractor.prime(estimate.image, frame_size=(frames[0].shape[1], frames[0].shape[0]))
        self._learn_clip(small, estimate)

    def _learn_clip(self, small: np.ndarray, estimate: ClipBackground, threads: int = 1) -> None:
        """Use the primed subtractor with the clip's unreliable zone (``estimate``), its variance
        floor retuned on the working-size frames ``small`` (N, h, w, 3) by ``threads``."""
        sub = self.subtractor
        if self.adapt_noise_floor:
            var_min = choose_var_min(sub.primed_model, small, threads)
            if var_min != sub.var_min:
                sub.retune(var_min)
        self.background = ClipBackground(sub.reference, estimate.unreliable)
        self.refiner = None

    def learn_zone(self, frames, median: np.ndarray | None = None, threads: int = 1) -> None:
        """After :meth:`prime` with the clip's median image, learn its unreliable zone and
        variance floor from the same frames (list or (N, H, W, 3) BGR uint8), before frame 1;
        ``median``: that image if the frames are at working size; ``threads``: measuring floors."""
        if self.subtractor.reference is None:
            raise ExtractionError("learn_zone needs prime() with a background image first")
        small = self._working_frames(list(frames))
        if median is not None and median.shape != small.shape[1:]:
            median = None
        self._learn_clip(small, clip_background(small, median=median), threads)

    def _working_frames(self, frames: list) -> np.ndarray:
        """Frames (each BGR uint8 (H, W, 3)) shrunk to the working size, (N, h, w, 3)."""
        height, width = frames[0].shape[:2]
        size = self.subtractor.working_size(width, height)
        return np.stack([shrink(f, size) for f in frames])

    def __call__(self, frame: np.ndarray) -> list[PersonMask]:
        """People in ``frame`` (BGR uint8 (H, W, 3)); [] while the background is warming up."""
        learning_only = not self.subtractor.ready
        small, raw = self.subtractor.subtract(frame)
        if learning_only:
            return []
        _, foreground = cv2.threshold(raw, _FOREGROUND_LEVEL, 255, cv2.THRESH_BINARY)
        box = _padded_box(foreground, self.open_px + self.close_px + 2 * self.restore_px + 2)
        cleaned = np.zeros_like(foreground)
        if box is not None:
            cleaned[box] = self._cleaned(foreground[box], raw[box] == _SHADOW_LEVEL, small[box],
                                         box, raw.size)
        if self.refine and self.background is not None and self.background.unreliable.any():
            if self.refiner is None:
                from tracker.video.zone import ZoneRefiner
                self.refiner = ZoneRefiner(self.refine_relearn_every,
                                           trust_zone_foreground=self.trust_zone_foreground)
            cleaned = self.refiner(cleaned, small, raw == _SHADOW_LEVEL,
                                   self.background.unreliable)
        return person_masks(cleaned, (frame.shape[1], frame.shape[0]), self.min_area_fraction,
                            self.max_hole_fraction,
                            max_fragment_area=self.max_fragment_area, image=small)

    def _cleaned(self, mask: np.ndarray, shadow: np.ndarray, small: np.ndarray,
                 box: tuple[slice, slice], image_area: int) -> np.ndarray:
        """Cleaned foreground (uint8 (h, w), 255 = person) in ``box`` (rows, columns; all the
        foreground and more than the morphology reaches) from MOG2's foreground there (changed
        in place), shadow (bool) and frame (BGR uint8); image_area: px of the whole image."""
        if self.keep_enclosed_shadow:
            # Bodies enclose shadow, specks (flicker on a window, noise on the ceiling) do not.
            solid = clean_mask(mask, self.open_px, 1, self.restore_px) > 0
            mask |= enclosed_shadow(solid, shadow)
        cleaned = clean_mask(mask, self.open_px, self.close_px, self.restore_px)
        if self.drop_lighting and self.background is not None:
            cleaned = drop_lighting_blobs(cleaned, small, self.background.image[box],
                                          min_area=int(self.min_area_fraction * image_area))
        return cleaned


def _padded_box(mask: np.ndarray, margin: int) -> tuple[slice, slice] | None:
    """(rows, columns) slices of the box around the nonzero pixels of ``mask`` (uint8 (h, w)),
    widened by ``margin`` px on each side within the image; None when the mask is empty."""
    x, y, w, h = cv2.boundingRect(mask)           # of a uint8 image: its nonzero pixels
    if w == 0:
        return None
    height, width = mask.shape
    return (slice(max(y - margin, 0), min(y + h + margin, height)),
            slice(max(x - margin, 0), min(x + w + margin, width)))
