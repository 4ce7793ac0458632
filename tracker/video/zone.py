"""Where the background model is unreliable (a person who never leaves the spot): person or
background decided by colour by OpenCV's grabCut, seeded by background subtraction
(SilhouetteExtractor's ``refine``). Imported only for clips with such a zone.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from tracker.video.silhouettes import ExtractionError


def refine_in_zone(mask: np.ndarray, frame: np.ndarray, shadow: np.ndarray, zone: np.ndarray,
                   min_seed_area: int = 20, margin: float = 0.1, max_side_px: int = 400,
                   trust_zone_foreground: bool = True) -> np.ndarray:
    """Decide person or background by colour where the background model is unreliable.

    ``mask``: uint8 (h, w) foreground, 255 = person; ``frame``: BGR uint8 (h, w, 3); ``shadow``
    and ``zone``: bool (h, w), MOG2's shadow and the unreliable zone
    (tracker.video.background.clip_background). Each box of :func:`zone_boxes` is cut by
    grabCut on a copy shrunk to at most ``max_side_px`` (400: a person at working size is not
    shrunk; smaller lost thin legs): foreground sure person, background outside the zone sure
    background (shadow: probable), the rest of the zone probable person, so the colour models
    fill in the still torso the background model absorbed. ``trust_zone_foreground=False``
    makes the zone's foreground only probable too, so colour also removes ghosts (where the
    person stood in the median); :data:`COLLAPSED_SHARE` guards it. Figures:
    docs/code_notes/video.md. Returns a new mask; :class:`ZoneRefiner` keeps colour models.
    """
    out = mask.copy()
    for x0, y0, x1, y1 in zone_boxes(mask, zone, min_seed_area, margin):
        labels = _zone_labels(mask[y0:y1, x0:x1] > 0, shadow[y0:y1, x0:x1],
                              zone[y0:y1, x0:x1], trust_zone_foreground)
        cut = _grabcut(frame[y0:y1, x0:x1], labels, max_side_px)
        if not trust_zone_foreground:
            cut = _unless_collapsed(cut, frame[y0:y1, x0:x1], mask[y0:y1, x0:x1] > 0,
                                    shadow[y0:y1, x0:x1], zone[y0:y1, x0:x1], max_side_px)
        out[y0:y1, x0:x1] = cut
    return out


#: A colour cut (the zone's foreground only probable person) keeping less than this share of
#: the box's foreground has lost the person, not a ghost (ghosts are a part of it): the box is
#: cut again with the foreground sure (a rendered walker had lost 70 % of itself in a frame).
COLLAPSED_SHARE = 0.5


def _unless_collapsed(cut: np.ndarray, crop: np.ndarray, found: np.ndarray, shadow: np.ndarray,
                      zone: np.ndarray, max_side_px: int) -> np.ndarray:
    """cut (uint8 (h, w), 255 = person) of one box, or, when it keeps less than
    COLLAPSED_SHARE of the box's foreground found (bool (h, w)), the box cut with the
    foreground sure (grabCut learning anew)."""
    if np.count_nonzero(cut) >= COLLAPSED_SHARE * np.count_nonzero(found):
        return cut
    return _grabcut(crop, _zone_labels(found, shadow, zone, True), max_side_px)


def zone_boxes(mask: np.ndarray, zone: np.ndarray, min_seed_area: int = 20,
               margin: float = 0.1) -> list[tuple[int, int, int, int]]:
    """Boxes (x0, y0, x1, y1) px, end exclusive, that :func:`refine_in_zone` re-segments: one per
    blob of ``mask`` (uint8 (h, w), 255 = person) | ``zone`` (bool (h, w)) that touches the zone
    and has at least ``min_seed_area`` px of foreground outside it, padded by ``margin`` x its
    longer side + 2 px and clipped to the image."""
    both = cv2.bitwise_or(mask, zone.astype(np.uint8) * 255)
    contours, _ = cv2.findContours(both, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    height, width = mask.shape
    boxes = []
    for contour in contours:
        x, y, w, h = cv2.boundingRect(contour)
        pad = int(round(margin * max(w, h))) + 2
        x0, y0 = max(x - pad, 0), max(y - pad, 0)
        x1, y1 = min(x + w + pad, width), min(y + h + pad, height)
        if (zone[y:y + h, x:x + w].any() and np.count_nonzero(
                (mask[y0:y1, x0:x1] > 0) & ~zone[y0:y1, x0:x1]) >= min_seed_area):
            boxes.append((x0, y0, x1, y1))
    return boxes


def _zone_labels(found: np.ndarray, shadow: np.ndarray, zone: np.ndarray,
                 trust_zone_foreground: bool = True) -> np.ndarray:
    """grabCut seeds (h, w) uint8 GC_* from one box's foreground, shadow and zone (bool (h, w)):
    foreground outside the zone sure person, the zone (foreground in it too, unless
    trust_zone_foreground) probable person, shadow outside it probable background, everything
    else sure background."""
    labels = np.full(found.shape, cv2.GC_BGD, np.uint8)
    labels[shadow] = cv2.GC_PR_BGD
    labels[zone] = cv2.GC_PR_FGD
    sure = found if trust_zone_foreground else found & ~zone
    labels[sure] = cv2.GC_FGD
    return labels


@dataclass(frozen=True)
class _ColourModels:
    """grabCut's colour models learned in one box: ``box`` (x0, y0, x1, y1) px; ``background``
    and ``person``: float64 (1, 65), OpenCV's 5-component GMMs; ``used``: frames cut with them
    since they were learned."""

    box: tuple[int, int, int, int]
    background: np.ndarray
    person: np.ndarray
    used: int = 0


def _box_iou(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> float:
    """Intersection over union of two boxes (x0, y0, x1, y1)."""
    w = max(0, min(a[2], b[2]) - max(a[0], b[0]))
    h = max(0, min(a[3], b[3]) - max(a[1], b[1]))
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - w * h
    return w * h / union if union > 0 else 0.0


class ZoneRefiner:
    """:func:`refine_in_zone` for a video: grabCut's colour models are learned in a box every
    ``relearn_every`` frames; in between, the box is cut (every frame, on its own pixels) with
    the models kept from the previous frame's box it overlaps most (IoU at least ``min_iou``):
    learning is most of grabCut's cost, and the models change little while the same person
    stands before the same background (figures: docs/code_notes/video.md). Other arguments:
    :func:`refine_in_zone`'s. ``learned`` and ``kept`` count the boxes cut each way.
    """

    def __init__(self, relearn_every: int = 3, min_iou: float = 0.5, min_seed_area: int = 20,
                 margin: float = 0.1, max_side_px: int = 400,
                 trust_zone_foreground: bool = True):
        if relearn_every < 1 or not 0.0 <= min_iou <= 1.0:
            raise ExtractionError(f"ZoneRefiner: relearn_every={relearn_every} must be >= 1 "
                                  f"and min_iou={min_iou} in [0, 1]")
        self.relearn_every, self.min_iou = relearn_every, min_iou
        self.min_seed_area, self.margin, self.max_side_px = min_seed_area, margin, max_side_px
        self.trust_zone_foreground = trust_zone_foreground
        self.learned = 0
        self.kept = 0
        self._models: list[_ColourModels] = []

    def __call__(self, mask: np.ndarray, frame: np.ndarray, shadow: np.ndarray,
                 zone: np.ndarray) -> np.ndarray:
        """As :func:`refine_in_zone` (same arguments and result), for the next frame."""
        out = mask.copy()
        models = []
        for box in zone_boxes(mask, zone, self.min_seed_area, self.margin):
            x0, y0, x1, y1 = box
            labels = _zone_labels(mask[y0:y1, x0:x1] > 0, shadow[y0:y1, x0:x1],
                                  zone[y0:y1, x0:x1], self.trust_zone_foreground)
            previous = self._reusable(box)
            if previous is None:
                cut, bgd, fgd = _grabcut_models(frame[y0:y1, x0:x1], labels, self.max_side_px)
                if bgd is not None:           # nothing learned: learn again next frame
                    models.append(_ColourModels(box, bgd, fgd))
                self.learned += 1
            else:
                cut, _, _ = _grabcut_models(frame[y0:y1, x0:x1], labels, self.max_side_px,
                                            (previous.background, previous.person))
                models.append(_ColourModels(box, previous.background, previous.person,
                                            previous.used + 1))
                self.kept += 1
            if not self.trust_zone_foreground:
                cut = _unless_collapsed(cut, frame[y0:y1, x0:x1], mask[y0:y1, x0:x1] > 0,
                                        shadow[y0:y1, x0:x1], zone[y0:y1, x0:x1],
                                        self.max_side_px)
            out[y0:y1, x0:x1] = cut
        self._models = models
        return out

    def _reusable(self, box: tuple[int, int, int, int]) -> _ColourModels | None:
        """The kept models to cut this box with, or None when they must be learned."""
        if not self._models:
            return None
        best = max(self._models, key=lambda m: _box_iou(m.box, box))
        if best.used + 1 >= self.relearn_every or _box_iou(best.box, box) < self.min_iou:
            return None
        return best


def _grabcut(crop: np.ndarray, labels: np.ndarray, max_side_px: int) -> np.ndarray:
    """grabCut (2 iterations) of a BGR crop seeded by GC_* labels (same (h, w)), on a copy
    shrunk to max_side_px; uint8 (h, w) 255 = person at the crop's size."""
    return _grabcut_models(crop, labels, max_side_px)[0]


def _grabcut_models(crop: np.ndarray, labels: np.ndarray, max_side_px: int,
                    models: tuple[np.ndarray, np.ndarray] | None = None, seed: int = 0
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """grabCut of a BGR crop seeded by GC_* labels (same (h, w)), on a copy shrunk to
    max_side_px: without ``models``, learned from the seeds (2 iterations, OpenCV's generator
    reset to ``seed``); with (background, person) float64 (1, 65) GMMs, one cut with them
    frozen. Returns (uint8 (h, w) 255 = person at the crop's size, the models used; both None
    when grabCut could not run)."""
    h, w = labels.shape
    scale = min(1.0, max_side_px / max(h, w))
    small = (max(1, round(w * scale)), max(1, round(h * scale)))
    image = cv2.resize(crop, small, interpolation=cv2.INTER_AREA)
    seeds = cv2.resize(labels, small, interpolation=cv2.INTER_NEAREST)
    if models is None:
        # grabCut's k-means draws from OpenCV's process-wide generator: unseeded, a view's masks
        # depended on what ran before (Pose2Sim cam02 1994 or 1995 keypoints covered).
        cv2.setRNGSeed(seed)
        bgd, fgd, iterations, mode = np.zeros((1, 65)), np.zeros((1, 65)), 2, cv2.GC_INIT_WITH_MASK
    else:
        bgd, fgd = models[0].copy(), models[1].copy()
        iterations, mode = 1, cv2.GC_EVAL_FREEZE_MODEL
    try:
        cv2.grabCut(image, seeds, None, bgd, fgd, iterations, mode)
    except cv2.error:                     # no sure background or person in the box: keep it
        seeds = cv2.resize(labels, small, interpolation=cv2.INTER_NEAREST)
        bgd = fgd = None
    person = ((seeds == cv2.GC_FGD) | (seeds == cv2.GC_PR_FGD)).astype(np.uint8) * 255
    person = cv2.resize(person, (w, h), interpolation=cv2.INTER_LINEAR)
    return np.where(person > 127, 255, 0).astype(np.uint8), bgd, fgd
