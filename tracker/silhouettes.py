"""Frames to person silhouettes: background subtraction, mask cleaning, one mask per person.

The subtractor works on a copy of the frame shrunk to ``working_width`` px (default 320): OpenCV's
MOG2 costs about 4x less at half of 640 px and a silhouette loses little, because each person's
mask is scaled back up to frame resolution with linear interpolation (smooth edges, not blocks).
Everything per frame is an OpenCV or numpy whole-image operation; Python loops run over people.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from regressor.errors import SilhouettePoseError

# MOG2 marks foreground 255 and shadow 127; anything above this threshold is foreground proper.
_FOREGROUND_LEVEL = 200


class ExtractionError(SilhouettePoseError, ValueError):
    """Bad settings or frames for silhouette extraction; one-line message naming the problem."""


@dataclass(frozen=True)
class PersonMask:
    """One person's silhouette in frame pixel coordinates.

    ``mask``: (h, w) bool crop, True on the person; ``bbox``: (x, y, w, h) px of the crop in the
    frame; ``centroid``: (x, y) px of the mask's centre of mass in the frame; ``area``: foreground
    pixels in ``mask``.
    """

    mask: np.ndarray
    bbox: tuple[int, int, int, int]
    centroid: tuple[float, float]
    area: int


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
    """

    def __init__(self, working_width: int = 320, history: int = 500,
                 background_ratio: float = 0.7, var_threshold: float = 16.0,
                 detect_shadows: bool = True, warmup_frames: int = 15,
                 learning_rate: float | None = None):
        if working_width < 16:
            raise ExtractionError(f"working_width={working_width} must be at least 16 px")
        if history < 1 or warmup_frames < 0:
            raise ExtractionError(f"history={history} must be >= 1 and warmup_frames="
                                  f"{warmup_frames} >= 0")
        if not 0.0 < background_ratio < 1.0:
            raise ExtractionError(f"background_ratio={background_ratio} must be in (0, 1)")
        if learning_rate is not None and not 0.0 <= learning_rate <= 1.0:
            raise ExtractionError(f"learning_rate={learning_rate} must be in [0, 1]")
        self.working_width = working_width
        self.warmup_frames = warmup_frames
        self.learning_rate = 1.0 / history if learning_rate is None else learning_rate
        self.frames_seen = 0
        self._frame_size: tuple[int, int] | None = None
        self._model = cv2.createBackgroundSubtractorMOG2(
            history=history, varThreshold=var_threshold, detectShadows=detect_shadows)
        self._model.setBackgroundRatio(background_ratio)

    @property
    def ready(self) -> bool:
        """True once the warm-up frames have been seen."""
        return self.frames_seen >= self.warmup_frames

    def working_size(self, width: int, height: int) -> tuple[int, int]:
        """(width, height) px of the image the model works on for a frame of width x height."""
        if width <= self.working_width:
            return width, height
        return self.working_width, max(1, round(height * self.working_width / width))

    def prime(self, background: np.ndarray) -> None:
        """Learn the background from an image of the empty scene (BGR uint8 (H, W, 3)).

        Feeds it ``max(warmup_frames, 1)`` times at MOG2's fast start-up rate, after which the
        model is :attr:`ready`. With the :func:`median_background` of frames spread over a video
        this avoids the "ghost" a person present during a warm-up on live frames leaves behind.
        """
        for _ in range(max(self.warmup_frames - self.frames_seen, 1)):
            self.apply(background)

    def apply(self, frame: np.ndarray) -> np.ndarray:
        """Update the model with ``frame`` (BGR uint8 (H, W, 3)) and return its foreground mask.

        Returns uint8 (h, w) at :meth:`working_size`, 255 = foreground, 0 = background or shadow.
        All frames given to one subtractor must have the same size.
        """
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            raise ExtractionError(f"frame must be BGR uint8 (H, W, 3), got {frame.dtype} "
                                  f"{frame.shape}")
        size = (frame.shape[1], frame.shape[0])
        if self._frame_size is None:
            self._frame_size = size
        elif size != self._frame_size:
            raise ExtractionError(f"frame size changed from {self._frame_size[0]}x"
                                  f"{self._frame_size[1]} to {size[0]}x{size[1]}")
        work = self.working_size(*size)
        small = frame if work == size else cv2.resize(frame, work, interpolation=cv2.INTER_AREA)
        rate = -1.0 if not self.ready else self.learning_rate
        raw = self._model.apply(small, learningRate=rate)
        self.frames_seen += 1
        _, foreground = cv2.threshold(raw, _FOREGROUND_LEVEL, 255, cv2.THRESH_BINARY)
        return foreground


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


def clean_mask(mask: np.ndarray, open_px: int = 3, close_px: int = 5) -> np.ndarray:
    """Remove speckle and bridge small gaps in a foreground mask.

    ``mask``: uint8 (h, w), 255 = foreground. ``open_px``/``close_px``: elliptical kernel sizes
    (px) of the opening (drops specks) and closing (joins nearby fragments); <= 1 skips a step.
    Returns uint8 (h, w), 255 = foreground. Holes are filled later, per person, in
    :func:`person_masks`.
    """
    cleaned = mask
    if open_px > 1:
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (open_px, open_px))
        cleaned = cv2.morphologyEx(cleaned, cv2.MORPH_OPEN, kernel)
    if close_px > 1:
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (close_px, close_px))
        cleaned = cv2.morphologyEx(cleaned, cv2.MORPH_CLOSE, kernel)
    return cleaned


def person_masks(mask: np.ndarray, frame_size: tuple[int, int], min_area_fraction: float = 0.003,
                 max_hole_fraction: float = 0.002, merge_fragments: bool = True
                 ) -> list[PersonMask]:
    """Split a cleaned foreground mask into one :class:`PersonMask` per 8-connected component.

    ``mask``: uint8 (h, w) at the working size, 255 = foreground. ``frame_size``: (width, height)
    px of the original frame; each person's crop is scaled up to it (linear interpolation,
    threshold at half). ``min_area_fraction``: components smaller than this fraction of the image
    are dropped as clutter. ``max_hole_fraction``: holes (enclosed background) up to this fraction
    of the image are filled as subtraction dropouts; larger ones are kept, because a gap such as
    between an arm on the hip and the torso is real background the pose depends on.
    ``merge_fragments``: join components that look like pieces of one person (see
    :func:`_fragment_groups`); False gives exactly one person per component.
    Returns people sorted by area, largest first. Two people touching form one component.
    """
    height, width = mask.shape
    image_area = float(height * width)
    # Contours with a two-level hierarchy (outer boundaries, their holes) are ~20x cheaper than
    # connectedComponentsWithStats here, and filling them reproduces each component exactly.
    contours, hierarchy = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return []
    parents = hierarchy[0][:, 3]
    areas = np.array([cv2.contourArea(c) for c in contours])
    # contourArea runs through boundary pixel centres, so it undercounts by about half the
    # perimeter; the gate only needs to reject clutter, the reported area is counted exactly.
    outers = np.flatnonzero((parents == -1) & (areas >= min_area_fraction * image_area))
    big_holes = np.flatnonzero((parents != -1) & (areas > max_hole_fraction * image_area))
    rects = np.array([cv2.boundingRect(contours[o]) for o in outers]).reshape(-1, 4)
    people = []
    groups = _fragment_groups(rects) if merge_fragments else [[i] for i in range(len(rects))]
    for group in groups:
        members = [int(outers[g]) for g in group]
        holes = [contours[h] for h in big_holes if parents[h] in members]
        people.append(_person_from_contours(contours, members, holes, mask.shape, frame_size))
    return sorted((p for p in people if p is not None), key=lambda p: -p.area)


def _fragment_groups(rects: np.ndarray, min_overlap: float = 0.5,
                     max_gap: float = 0.25) -> list[list[int]]:
    """Group the components (bounding rects (n, 4) x, y, w, h px) that are pieces of one
    person: where skin or clothes match the background, subtraction can cut a person in two
    at the waist or neck. Two pieces belong together when their x-ranges overlap by at least
    min_overlap of the narrower one and the vertical gap between them is at most max_gap of
    the taller one. (People side by side do not overlap in x; one standing behind another
    usually touches and is one component anyway.)"""
    n = len(rects)
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
    for i, j in zip(*np.nonzero(np.triu(joined, 1))):
        group[root(int(j))] = root(int(i))
    groups: dict[int, list[int]] = {}
    for i in range(n):
        groups.setdefault(root(i), []).append(i)
    return list(groups.values())


def _person_from_contours(contours, members: list[int], holes: list[np.ndarray],
                          shape: tuple[int, int], frame_size: tuple[int, int]
                          ) -> PersonMask | None:
    """Rasterize one person (its component pieces minus their kept holes) and scale it to
    frame pixels. Pieces of one person are joined across the gap between them."""
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
    return PersonMask(crop > 0, (x0, y0, x1 - x0, y1 - y0), centroid, int(moments["m00"]))


def _bridge_vertical_gaps(crop: np.ndarray, rects) -> np.ndarray:
    """Close the vertical gaps between pieces with a vertical closing just taller than the
    widest gap (padded, so background open to the crop's edge is never filled)."""
    tops = sorted((r[1], r[1] + r[3]) for r in rects)
    widest = max([0] + [b_top - a_bottom for (_, a_bottom), (b_top, _) in zip(tops, tops[1:])])
    k = int(widest) + 3
    padded = cv2.copyMakeBorder(crop, k, k, 0, 0, cv2.BORDER_CONSTANT, value=0)
    kernel = np.ones((k, 1), np.uint8)
    closed = cv2.morphologyEx(padded, cv2.MORPH_CLOSE, kernel)
    return closed[k:-k]


class SilhouetteExtractor:
    """Frame -> list of :class:`PersonMask`: subtraction, cleaning and splitting in one call.

    Keyword arguments go to :class:`BackgroundSubtractor`; ``open_px`` and ``close_px`` to
    :func:`clean_mask` (working-resolution px); ``min_area_fraction`` and ``max_hole_fraction``
    to :func:`person_masks`.
    """

    def __init__(self, open_px: int = 3, close_px: int = 5, min_area_fraction: float = 0.003,
                 max_hole_fraction: float = 0.002, **subtractor_options):
        self.subtractor = BackgroundSubtractor(**subtractor_options)
        self.open_px, self.close_px = open_px, close_px
        self.min_area_fraction = min_area_fraction
        self.max_hole_fraction = max_hole_fraction

    def prime(self, background: np.ndarray) -> None:
        """Learn the empty scene first; see :meth:`BackgroundSubtractor.prime`."""
        self.subtractor.prime(background)

    def __call__(self, frame: np.ndarray) -> list[PersonMask]:
        """People in ``frame`` (BGR uint8 (H, W, 3)); [] while the background is warming up."""
        learning_only = not self.subtractor.ready
        foreground = self.subtractor.apply(frame)
        if learning_only:
            return []
        cleaned = clean_mask(foreground, self.open_px, self.close_px)
        return person_masks(cleaned, (frame.shape[1], frame.shape[0]), self.min_area_fraction,
                            self.max_hole_fraction)
