"""Frames to person silhouettes: background subtraction, mask cleaning, one mask per person.

The subtractor works on a copy of the frame shrunk to ``working_width`` px (default 320): OpenCV's
MOG2 costs about 4x less at half of 640 px and a silhouette loses little, because each person's
mask is scaled back up to frame resolution with linear interpolation (smooth edges, not blocks).
Everything per frame is an OpenCV or numpy operation on the whole image or on the box around
its foreground (the mask cleaning); Python loops run over people.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

from regressor.errors import SilhouettePoseError
from tracker.video.area_shrink import shrink
from tracker.video.background import (MIN_GAIN_CHANGE, ClipBackground, GainMeter, clean_plate,
                         clip_background, undo_gain)
from tracker.video.noise_floor import FOREGROUND_LEVEL as _FOREGROUND_LEVEL, choose_var_min

_SHADOW_LEVEL = 127              # MOG2's mark for shadow (foreground: _FOREGROUND_LEVEL)
# A frame darker or brighter than the background by more than this factor in some channel (a
# black or blank frame, a flash, a cut to another scene) shows no one: it cannot be undone
# (a black frame's gain is 0), and subtracted as it is, the whole image was one "person".
_MAX_GAIN_FACTOR = 4.0
#: Components larger than this fraction of the image are not people (a change of the whole
#: scene): a standing person filling a portrait frame's height covers about 15-35 %.
DEFAULT_MAX_AREA_FRACTION = 0.5
#: Components smaller than this fraction of the image are clutter, not people: at 640x480 a
#: walker about 55 px tall or more passes (a 320x240 video: about 28 px); smaller walkers'
#: headings became unreliable (docs/tuning.md, "tracker/video/silhouettes.py").
DEFAULT_MIN_AREA_FRACTION = 0.0015
# OpenCV MOG2's default cap on a pixel's variance (grey levels squared).
_MOG2_VAR_MAX = 75.0


class ExtractionError(SilhouettePoseError, ValueError):
    """Bad settings or frames for silhouette extraction; one-line message naming the problem."""


@dataclass(frozen=True)
class PersonMask:
    """One person's silhouette in frame pixel coordinates.

    ``mask``: (h, w) bool crop, True on the person; ``bbox``: (x, y, w, h) px of the crop in the
    frame; ``centroid``: (x, y) px of the mask's centre of mass in the frame; ``area``: foreground
    pixels in ``mask``; ``colour``: the person's appearance, :func:`colour_histogram` of the
    frame inside the silhouette (COLOUR_BINS,), or None when not measured.
    """

    mask: np.ndarray
    bbox: tuple[int, int, int, int]
    centroid: tuple[float, float]
    area: int
    colour: np.ndarray | None = None


#: Bins of a person's colour histogram over hue, saturation and value (OpenCV's HSV, hue 0-180):
#: hue and saturation tell clothes apart under the same light, value tells black from white.
COLOUR_BINS_HSV = (8, 4, 4)
COLOUR_BINS = int(np.prod(COLOUR_BINS_HSV))


def colour_histogram(image: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The colour of ``image`` (BGR uint8 (h, w, 3)) where ``mask`` (uint8 (h, w), nonzero =
    person): a HSV histogram (COLOUR_BINS,) float32 summing to 1 (all zeros for an empty
    mask). Compared by Bhattacharyya distance (tracker.tracks.association), it tells people apart
    where their silhouettes cannot."""
    hsv = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
    hist = cv2.calcHist([hsv], [0, 1, 2], mask, list(COLOUR_BINS_HSV), [0, 180, 0, 256, 0, 256])
    total = float(hist.sum())
    return (hist.ravel() / total if total else hist.ravel()).astype(np.float32)


class BackgroundSubtractor:
    """MOG2 background model on a downscaled frame, shadows removed.

    ``working_width``: px width the model works at (frames are shrunk to it, never enlarged), so
    the cost per frame does not grow with the video's resolution. ``history``: frames the model
    remembers. ``background_ratio``: MOG2's share of weight that counts as background; a person
    who stands still becomes background after about ln(background_ratio) / ln(1 - 1/history)
    frames (0.7 and 500: ~180 frames, 6 s at 30 fps; MOG2's default 0.9 would give ~50).
    Lower values keep still people longer but treat a flickering background as foreground.
    ``var_threshold``: MOG2's squared Mahalanobis distance for foreground. ``warmup_frames``:
    frames used only to learn the background (fast, at MOG2's rate 1/frames seen), during which
    :attr:`ready` is False.
    ``learning_rate``: the rate after warm-up; None means 1/history (MOG2's own automatic rate
    would still be 1/frames seen, which swallows a person standing still within a second);
    0 freezes the model after warm-up (static camera and light).
    ``normalise_brightness``: undo global brightness changes against the primed background
    (see :meth:`subtract`). ``var_min``: MOG2's floor on each pixel's variance, grey levels
    squared (its default 4 suits a clean camera; a compressed video needs more, see
    :mod:`tracker.video.noise_floor` and :meth:`retune`).
    """

    def __init__(self, working_width: int = 320, history: int = 500,
                 background_ratio: float = 0.7, var_threshold: float = 16.0,
                 detect_shadows: bool = True, warmup_frames: int = 15,
                 learning_rate: float | None = None, normalise_brightness: bool = True,
                 var_min: float = 4.0):
        if working_width < 16:
            raise ExtractionError(f"working_width={working_width} must be at least 16 px")
        if history < 1 or warmup_frames < 0:
            raise ExtractionError(f"history={history} must be >= 1 and warmup_frames="
                                  f"{warmup_frames} >= 0")
        if not 0.0 < background_ratio < 1.0:
            raise ExtractionError(f"background_ratio={background_ratio} must be in (0, 1)")
        if learning_rate is not None and not 0.0 <= learning_rate <= 1.0:
            raise ExtractionError(f"learning_rate={learning_rate} must be in [0, 1]")
        _check_var_min(var_min)
        self.working_width = working_width
        self.warmup_frames = warmup_frames
        self.learning_rate = 1.0 / history if learning_rate is None else learning_rate
        self.normalise_brightness = normalise_brightness
        #: Background at working size the brightness gain is measured against (set by prime).
        self.reference: np.ndarray | None = None
        self.frames_seen = 0
        self._frame_size: tuple[int, int] | None = None
        self._mog2_options = dict(history=history, varThreshold=var_threshold,
                                  detectShadows=detect_shadows)
        self._background_ratio = background_ratio
        self.var_min = float(var_min)
        self._model = self.new_model(self.var_min)

    def new_model(self, var_min: float):
        """A fresh, unprimed OpenCV MOG2 with this subtractor's settings and variance floor
        ``var_min`` (grey levels squared)."""
        model = cv2.createBackgroundSubtractorMOG2(**self._mog2_options)
        model.setBackgroundRatio(self._background_ratio)
        model.setVarMin(float(var_min))
        # MOG2 starts a new Gaussian at varInit (15 by default): below the floor it would
        # start tighter than the floor allows.
        model.setVarInit(max(model.getVarInit(), float(var_min)))
        return model

    def primed_model(self, var_min: float):
        """A fresh MOG2 (:meth:`new_model`) that has learned the primed :attr:`reference` as
        :meth:`prime` teaches it: ``max(warmup_frames, 1)`` times at MOG2's start-up rate."""
        if self.reference is None:
            raise ExtractionError("a primed model needs prime() first")
        model = self.new_model(var_min)
        for _ in range(max(self.warmup_frames, 1)):
            model.apply(self.reference, learningRate=-1.0)
        return model

    def retune(self, var_min: float) -> None:
        """Rebuild the background model with variance floor ``var_min`` (grey levels squared)
        and re-learn the primed :attr:`reference` as :meth:`prime` did."""
        if self.reference is None:
            raise ExtractionError("retune needs prime() first")
        _check_var_min(var_min)
        self.var_min = float(var_min)
        self._model = self.primed_model(self.var_min)

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
        """Learn the background from an image of the empty scene (BGR uint8 (H, W, 3)).

        frame_size: None when ``background`` is at the size of the frames to come; else the
        frames' (width, height) px, and ``background`` is already at :meth:`working_size` for
        them (a median of shrunk frames: scaling it up and back down would blur it, and a
        blurred background makes every textured pixel of a sharp frame differ from it; Pose2Sim
        1920x1080 views: 3-4x more specks in the foreground).

        Feeds it ``max(warmup_frames, 1)`` times at MOG2's fast start-up rate, after which the
        model is :attr:`ready`. With the :func:`median_background` of frames spread over a video
        this avoids the "ghost" a person present during a warm-up on live frames leaves behind.
        """
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
        for _ in range(max(self.warmup_frames - self.frames_seen, 1)):
            self._model.apply(small, learningRate=-1.0 if not self.ready else self.learning_rate)
            self.frames_seen += 1
        self.reference = small.copy()
        self._gain = GainMeter(self.reference)

    def _check_frame_size(self, size: tuple[int, int]) -> None:
        """Remember the frames' (width, height) px on first use; refuse any other size later."""
        if self._frame_size is None:
            self._frame_size = size
        elif size != self._frame_size:
            raise ExtractionError(f"frame size changed from {self._frame_size[0]}x"
                                  f"{self._frame_size[1]} to {size[0]}x{size[1]}")

    def apply(self, frame: np.ndarray) -> np.ndarray:
        """Update the model with ``frame`` (BGR uint8 (H, W, 3)) and return its foreground mask.

        Returns uint8 (h, w) at :meth:`working_size`, 255 = foreground, 0 = background or shadow.
        All frames given to one subtractor must have the same size.
        """
        _, raw = self.subtract(frame)
        _, foreground = cv2.threshold(raw, _FOREGROUND_LEVEL, 255, cv2.THRESH_BINARY)
        return foreground

    def subtract(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Update the model with ``frame`` (BGR uint8 (H, W, 3)); returns (the frame at
        :meth:`working_size`, brightness-normalised, BGR uint8 (h, w, 3); MOG2's raw mask
        uint8 (h, w): 255 foreground, 127 shadow, 0 background).

        Once a :attr:`reference` background is set (by :meth:`prime`), a global brightness
        change (clouds, auto-exposure) is undone first: the frame is divided by its median
        per-channel gain over the reference when that is more than 3 % away from 1. A frame
        whose gain is beyond a factor of 4 either way (black, blank, a flash) gets an empty mask
        and leaves the model as it was."""
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
                # Nobody can be told from such a frame; the model does not learn it either.
                self.frames_seen += 1
                return small, np.zeros(small.shape[:2], np.uint8)
            if max(1.0 - low, high - 1.0) > MIN_GAIN_CHANGE:
                # Where the brighter light clips the background, the frame cannot be undone:
                # such pixels are background, not a blob.
                expected = cv2.multiply(self.reference, tuple(float(g) for g in gain) + (0.0,))
                saturated = (expected.max(axis=2) >= 250) & (small.max(axis=2) >= 250)
                small = undo_gain(small, gain)
        rate = -1.0 if not self.ready else self.learning_rate
        raw = self._model.apply(small, learningRate=rate)
        if saturated is not None:
            raw[saturated] = 0
        self.frames_seen += 1
        return small, raw


def _check_var_min(var_min: float) -> None:
    # MOG2 caps each variance at varMax (75 by default): a floor above it means nothing.
    if not (np.isfinite(var_min) and 0.0 < var_min <= _MOG2_VAR_MAX):
        raise ExtractionError(f"var_min={var_min} must be in (0, {_MOG2_VAR_MAX:g}] grey levels "
                              "squared")


def median_background(frames: list[np.ndarray]) -> np.ndarray:
    """Per-pixel median of frames (each BGR uint8 (H, W, 3)) -> BGR uint8 (H, W, 3).

    Taken over frames spread across a video, it shows the empty scene wherever no one stood
    still for more than half of them.
    """
    if not frames:
        raise ExtractionError("median_background needs at least one frame")
    shapes = {f.shape for f in frames}
    if len(shapes) != 1:
        raise ExtractionError(f"median_background frames differ in shape: {sorted(shapes)}")
    return np.median(np.stack(frames), axis=0).astype(np.uint8)


def clean_mask(mask: np.ndarray, open_px: int = 3, close_px: int = 5,
               restore_px: int = 1) -> np.ndarray:
    """Remove speckle and bridge small gaps in a foreground mask.

    ``mask``: uint8 (h, w), 255 = foreground. ``open_px``/``close_px``: elliptical kernel sizes
    (px) of the opening (drops specks) and closing (joins nearby fragments); <= 1 skips a step.
    ``restore_px``: foreground the opening removed within this many px of what it kept is put
    back: the opening shaves a body's outline (corners, the last pixel of a toe or finger tip,
    the edges of a wrist ~3 px wide at working size), isolated specks stay removed (0: plain
    opening).
    Pose2Sim coverage with 1 instead of 0: 95.0 -> 96.7 % (cam01), 94.0 -> 95.0 % (cam02).
    Returns uint8 (h, w), 255 = foreground. Holes are filled later, per person, in
    :func:`person_masks`.
    """
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


_SQUARE_3 = np.ones((3, 3), np.uint8)


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
    """Split a cleaned foreground mask into one :class:`PersonMask` per 8-connected component.

    ``mask``: uint8 (h, w) at the working size, 255 = foreground. ``frame_size``: (width, height)
    px of the original frame; each person's crop is scaled up to it (linear interpolation,
    threshold at half). ``min_area_fraction``: components smaller than this fraction of the image
    are dropped as clutter; those larger than ``max_area_fraction`` as a change of the whole
    scene (a background learned from other frames, a light switched on), not a person.
    ``max_hole_fraction``: holes (enclosed background) up to this fraction
    of the image are filled as subtraction dropouts; larger ones are kept, because a gap such as
    between an arm on the hip and the torso is real background the pose depends on.
    ``merge_fragments``: join components that look like pieces of one person (see
    :func:`_fragment_groups`, which also gets ``max_fragment_area``; 0 joins only pieces
    stacked one above the other); False gives exactly one person per component. ``image``:
    the frame at the mask's size (BGR uint8 (h, w, 3)) to measure each person's colour from
    (PersonMask.colour; None: not measured).
    Returns people sorted by area, largest first. Two people touching form one component.
    """
    height, width = mask.shape
    image_area = float(height * width)
    box = _padded_box(mask, 0)
    if box is None:
        return []
    # Contours with a two-level hierarchy (outer boundaries, their holes) are ~20x cheaper than
    # connectedComponentsWithStats here, and filling them reproduces each component exactly.
    # Traced in the box around the foreground only (OpenCV pads the image with background):
    # the same contours, in image coordinates, for the box's cost.
    contours, hierarchy = cv2.findContours(mask[box], cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE,
                                           offset=(box[1].start, box[0].start))
    parents = hierarchy[0][:, 3]
    areas = np.array([cv2.contourArea(c) for c in contours])
    # contourArea runs through boundary pixel centres, so it undercounts by about half the
    # perimeter; the gate only needs to reject clutter, the reported area is counted exactly.
    outers = np.flatnonzero((parents == -1) & (areas >= min_area_fraction * image_area)
                            & (areas <= max_area_fraction * image_area))
    big_holes = np.flatnonzero((parents != -1) & (areas > max_hole_fraction * image_area))
    rects = np.array([cv2.boundingRect(contours[o]) for o in outers]).reshape(-1, 4)
    people = []
    groups = (_fragment_groups(rects, areas[outers], max_fragment_area=max_fragment_area)
              if merge_fragments else [[i] for i in range(len(rects))])
    for group in groups:
        members = [int(outers[g]) for g in group]
        holes = [contours[h] for h in big_holes if parents[h] in members]
        people.append(_person_from_contours(contours, members, holes, mask.shape, frame_size,
                                            image))
    return sorted((p for p in people if p is not None), key=lambda p: -p.area)


def _fragment_groups(rects: np.ndarray, areas: np.ndarray | None = None,
                     min_overlap: float = 0.5, max_gap: float = 0.25,
                     max_fragment_area: float = 0.15) -> list[list[int]]:
    """Group the components (bounding rects (n, 4) x, y, w, h px; areas (n,) px) that are
    pieces of one person: where skin or clothes match the background, subtraction can cut a
    person in two at the waist or neck, or leave a foot or a hand apart. Two pieces belong
    together when their x-ranges overlap by at least min_overlap of the narrower one and the
    vertical gap between them is at most max_gap of the taller one; or when the smaller has at
    most max_fragment_area of the larger's area, lies no more than max_gap of the larger's
    height from its box on every side, and its centre is not above the larger's top (a foot, a
    hand, a floor blob at the feet). (People side by side do not overlap in x and are of like
    size; one standing behind another usually touches and is one component anyway.)"""
    n = len(rects)
    if n < 2:
        return [[i] for i in range(n)]
    group = list(range(n))

    def root(i: int) -> int:
        while group[i] != i:
            i = group[i]
        return i

    x0, y0 = rects[:, 0], rects[:, 1]
    x1, y1 = x0 + rects[:, 2], y0 + rects[:, 3]
    overlap = np.minimum(x1[:, None], x1[None, :]) - np.maximum(x0[:, None], x0[None, :])
    narrower = np.minimum(rects[:, 2][:, None], rects[:, 2][None, :])
    gap = np.maximum(y0[:, None], y0[None, :]) - np.minimum(y1[:, None], y1[None, :])
    taller = np.maximum(rects[:, 3][:, None], rects[:, 3][None, :])
    joined = (overlap >= min_overlap * narrower) & (gap <= max_gap * taller)
    if areas is not None:
        reach = max_gap * taller
        small = areas[:, None] <= max_fragment_area * areas[None, :]      # i a fragment of j
        near = (-overlap <= reach) & (gap <= reach)
        below_top = (y0 + rects[:, 3] / 2)[:, None] >= y0[None, :]
        fragment = small & near & below_top
        joined |= fragment | fragment.T
    for i, j in zip(*np.nonzero(np.triu(joined, 1))):
        group[root(int(j))] = root(int(i))
    groups: dict[int, list[int]] = {}
    for i in range(n):
        groups.setdefault(root(i), []).append(i)
    return list(groups.values())


def _person_from_contours(contours, members: list[int], holes: list[np.ndarray],
                          shape: tuple[int, int], frame_size: tuple[int, int],
                          image: np.ndarray | None = None) -> PersonMask | None:
    """Rasterize one person (its component pieces minus their kept holes) and scale it to
    frame pixels. Pieces of one person are joined across the gap between them. Its colour
    is measured in ``image`` (at the mask's size) when given, before scaling (cheaper)."""
    height, width = shape
    frame_width, frame_height = frame_size
    sx, sy = frame_width / width, frame_height / height
    pts = np.vstack([contours[m].reshape(-1, 2) for m in members])
    x, y, w, h = cv2.boundingRect(pts)
    crop = np.zeros((h, w), np.uint8)
    for m in members:
        cv2.drawContours(crop, contours, m, 255, cv2.FILLED, offset=(-x, -y))
    if holes:
        # A hole's contour runs through the foreground pixels around it: erase the inside,
        # then restore that rim.
        cv2.drawContours(crop, holes, -1, 0, cv2.FILLED, offset=(-x, -y))
        cv2.drawContours(crop, holes, -1, 255, 1, offset=(-x, -y))
    if len(members) > 1:
        crop = _bridge_vertical_gaps(crop, [cv2.boundingRect(contours[m]) for m in members])
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


def _bridge_vertical_gaps(crop: np.ndarray, rects) -> np.ndarray:
    """Close the vertical gaps between pieces with a vertical closing just taller than the
    widest gap (padded, so background open to the crop's edge is never filled)."""
    tops = sorted((r[1], r[1] + r[3]) for r in rects)
    widest = max([0] + [b_top - a_bottom for (_, a_bottom), (b_top, _) in zip(tops, tops[1:])])
    k = int(widest) + 3
    k += 1 - k % 2                # odd: an even kernel's off-centre anchor shifts the closing
    padded = cv2.copyMakeBorder(crop, k, k, 0, 0, cv2.BORDER_CONSTANT, value=0)
    kernel = np.ones((k, 1), np.uint8)
    closed = cv2.morphologyEx(padded, cv2.MORPH_CLOSE, kernel)
    return closed[k:-k]


def enclosed_shadow(foreground: np.ndarray, shadow: np.ndarray) -> np.ndarray:
    """The shadow pixels that lie inside a body: uint8 (h, w) 255 where ``shadow`` (bool
    (h, w)) has foreground (bool (h, w)) both above and below it in its column. Dark clothing
    (shorts between torso and legs, a dark shirt under the head) is enclosed so; a shadow cast
    on the ground is not, since nothing of the body stands below it in the image. Whole-image
    operations (first and last foreground row per column), no per-pixel Python."""
    out = np.zeros(shadow.shape, np.uint8)
    shadow_cols = np.flatnonzero(shadow.any(axis=0))
    if not len(shadow_cols):
        return out
    shadow_rows = np.flatnonzero(shadow.any(axis=1))
    # Only the box around the shadow can change: the columns' scans are made there alone.
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
    """Remove from ``mask`` (uint8 (h, w), 255 = foreground) the blobs where the frame is the
    background under other light (frame and background BGR uint8 (h, w, 3)): inside the blob
    either the grey levels correlate above ``min_correlation`` (same texture, only brightness
    and contrast changed), or every pixel and channel changed by the same factor (the median
    absolute deviation of log(frame / background) is under ``max_ratio_spread``: a plain
    surface lit differently, or a soft shadow). A person in front of the background does
    neither. Blobs under ``min_area`` px are left to the area gate. Returns a new mask."""
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
    """Whether a blob's pixels, frame and background BGR uint8 (n, 3), are the background under
    other light (:func:`drop_lighting_blobs`'s two tests; the ratio's spread, the dearer one,
    only when the correlation has not decided)."""
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
    log_ratio -= _median(log_ratio)
    return float(_median(np.abs(log_ratio, out=log_ratio))) < max_ratio_spread


def _median(values: np.ndarray) -> np.floating:
    """np.median of a 1-D float array (not empty), by a partial sort of it in place."""
    half = len(values) // 2
    if len(values) % 2:
        values.partition(half)
        return values[half]
    values.partition((half - 1, half))
    return (values[half - 1] + values[half]) / 2


class SilhouetteExtractor:
    """Frame -> list of :class:`PersonMask`: subtraction, cleaning and splitting in one call.

    Keyword arguments go to :class:`BackgroundSubtractor`; ``open_px``, ``close_px`` and
    ``restore_px`` to :func:`clean_mask` (working-resolution px); ``min_area_fraction``,
    ``max_hole_fraction`` and ``max_fragment_area`` to :func:`person_masks`.
    ``keep_enclosed_shadow``: shadow pixels inside a body's outline (enclosed by solid
    foreground, not by specks) count as person (dark clothing; :func:`enclosed_shadow`).
    ``drop_lighting``: drop blobs that are the background under other light
    (:func:`drop_lighting_blobs`). ``refine``: re-segment people by colour where the background
    is unreliable (tracker.video.zone; only after :meth:`prime` with frames of the clip),
    learning grabCut's colour models every ``refine_relearn_every`` frames (1: every frame), the
    foreground in the zone sure person unless ``trust_zone_foreground`` is False.
    ``adapt_noise_floor``: when frames of the clip are given (:meth:`prime` with frames,
    :meth:`learn_zone`), raise the background model's variance floor until its foreground on
    them is no longer speckled (:func:`tracker.video.noise_floor.choose_var_min`; compressed video);
    an explicit ``var_min`` keyword turns it off.
    """

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
        self.min_area_fraction = min_area_fraction
        self.max_hole_fraction = max_hole_fraction
        self.max_fragment_area = max_fragment_area
        self.keep_enclosed_shadow = keep_enclosed_shadow
        self.drop_lighting = drop_lighting
        self.refine = refine
        if refine_relearn_every < 1:
            raise ExtractionError(f"refine_relearn_every={refine_relearn_every} must be >= 1")
        self.refine_relearn_every = refine_relearn_every
        self.trust_zone_foreground = trust_zone_foreground
        #: The zone's tracker.video.zone.ZoneRefiner, made (and its module imported) only when
        #: a clip has a zone to refine.
        self.refiner = None
        self.background: ClipBackground | None = None

    def prime(self, background, frame_size: tuple[int, int] | None = None) -> None:
        """Learn the scene before the first frame. ``background``: either an image of the empty
        scene (a clean plate, BGR uint8 (H, W, 3), e.g. ``--background IMAGE`` or
        :func:`median_background`; at the working size when ``frame_size``, the frames' (width,
        height) px, is given: :meth:`BackgroundSubtractor.prime`), trusted everywhere; or
        frames spread over the clip (a list or (N, H, W, 3) array, e.g.
        ``VideoSource.sample_frames(25)``, frame_size unused), from which
        :func:`tracker.video.background.clip_background` estimates the scene and where it cannot be
        trusted (a person who never leaves the spot). See :meth:`BackgroundSubtractor.prime`."""
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
        height, width = frames[0].shape[:2]
        self.subtractor.prime(estimate.image, frame_size=(width, height))
        self._adapt_noise_floor(small)
        self.background = ClipBackground(self.subtractor.reference, estimate.unreliable)
        self.refiner = None

    def _adapt_noise_floor(self, small: np.ndarray) -> None:
        """Retune the primed subtractor's variance floor on working-size frames (N, h, w, 3)."""
        if not self.adapt_noise_floor:
            return
        sub = self.subtractor
        var_min = choose_var_min(sub.primed_model, small)
        if var_min != sub.var_min:
            sub.retune(var_min)

    def learn_zone(self, frames) -> None:
        """After :meth:`prime` with the clip's median image, mark where that background cannot
        be trusted, from the same frames (list or (N, H, W, 3) BGR uint8, any size that shrinks
        to the working size, e.g. ``sample_frames(25, size=working size)``): what priming with
        the frames does, without learning the median twice (the variance floor is chosen on
        them too, which re-learns the background: call it before the first frame)."""
        if self.subtractor.reference is None:
            raise ExtractionError("learn_zone needs prime() with a background image first")
        small = self._working_frames(list(frames))
        estimate = clip_background(small)
        self._adapt_noise_floor(small)
        self.background = ClipBackground(self.subtractor.reference, estimate.unreliable)
        self.refiner = None

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
        """The cleaned foreground (uint8 (h, w), 255 = person) of one ``box`` (rows, columns)
        of the working-size image, from MOG2's foreground there (uint8, 255; changed in place),
        its shadow (bool) and the frame (BGR uint8); image_area: px of the whole working-size
        image (the area gate is a fraction of it). The box holds all of the frame's
        foreground with a margin wider than the morphology reaches (_padded_box), so the result
        is the whole image's, cropped: the cleaning costs what the box's size does."""
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
    points = cv2.findNonZero(mask)
    if points is None:
        return None
    x, y, w, h = cv2.boundingRect(points)
    height, width = mask.shape
    return (slice(max(y - margin, 0), min(y + h + margin, height)),
            slice(max(x - margin, 0), min(x + w + margin, width)))
