"""Where the background model is unreliable (a person who never leaves the spot): person or
background decided by colour, with OpenCV's grabCut seeded by what background subtraction
found (tracker.video.silhouettes.SilhouetteExtractor's ``refine``). Imported only for clips
with such a zone.
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
    and ``zone``: bool (h, w), MOG2's shadow pixels and the background's unreliable zone
    (:func:`tracker.video.background.clip_background`). Each blob of mask | zone that touches the zone
    and has at least ``min_seed_area`` px of foreground outside it (a person is there and
    moving) is re-segmented inside its box (padded by ``margin``; :func:`zone_boxes`) with
    OpenCV's grabCut, on a copy shrunk to at most ``max_side_px`` (400: a person at the default
    working size is not shrunk; at 112 a leg ~8 px wide kept ~3 px and grabCut lost the standing
    leg; at 224, about 1.6x faster, Pose2Sim coverage was 2.2 points lower on cam03, 0.7 higher
    on cam02, within 0.6 on the others; at 400 this costs 67-76 ms per frame on the 320x569
    Pose2Sim views, on a loaded machine): foreground is sure person (also inside the zone, where
    the background model still sees most of a standing leg), background outside the zone sure
    background (shadow: probable background), the rest of the zone probable person; the colour
    models then fill in the still torso the background model had absorbed. Returns a new mask.
    :class:`ZoneRefiner` does the same, keeping grabCut's colour models between frames.

    ``trust_zone_foreground=False`` makes the foreground inside the zone only probable person
    too, so that colour also decides on ghosts: where the median showed the person and the
    person has since moved, the background differs from the median and the subtractor calls
    it foreground, and as sure person it stays on the mask (Pose2Sim's masks are person and
    background blobs). Measured on Pose2Sim (2026-12-02, ``scripts/evaluate_silhouettes.py
    --extractor after colour``, mean over the 4 views): the mask's share off the keypoints'
    body 0.254 -> 0.163, keypoint coverage 0.911 -> 0.860; through ``scripts/evaluate_real.py
    --zone-foreground colour`` knee/elbow flexion error 31.0 -> 25.1 degrees (the constant at
    the reference's mean 13.0). Its costs: a floor blob at the feet that the zone had glued to
    the body becomes a track of its own for a few frames (cam01: two, of 4 and 10 frames; one
    frame of the 16 small test frames), colour models kept between frames cut up to 6 % of the
    mask differently from models learned every frame (5 % with the rule above), and coverage
    falls; thin foreground kept sure (an opening of 3-9 px decides what is thick) gave masks
    between the two (flexion 26.7 at 5 px) with kept-model differences up to 10 %. ``track``'s
    default since 2026-12-04 (tracker.pipeline.TrackerSettings.trust_zone_foreground), chosen
    on rendered validation videos: where a walker stays in one region of a short clip, that
    region becomes the zone, and the sure rule kept its ghosts (12 validation videos, filtered
    corr8 0.447 -> 0.563, heading unchanged). This function's own default stays the sure rule.
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


#: A colour cut (foreground in the zone only probable person) that keeps less than this share
#: of the box's foreground has lost the person, not a ghost: the box is cut again with the
#: foreground sure. Ghosts are a part of the foreground (Pose2Sim: the mask's share off the
#: body 0.25 -> 0.16 with colour deciding); a rendered walker lost 70 % of itself in one frame
#: (tests/test_track_cli.py's two walkers: the track broke in two there).
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
    ``relearn_every`` frames; in between, the box is cut with the models kept from the previous
    frame's box it overlaps most (IoU at least ``min_iou``).

    The cut itself still runs every frame on that frame's pixels, so a limb that moves is
    followed; only the colour models, which change little while the same person stands in
    front of the same background, are kept. Learning them (k-means, then two rounds of
    re-estimation) is most of grabCut's cost: on a 386x225 Pose2Sim box 47 ms learning and
    cutting against 18 ms cutting with kept models, the two masks differing in 1 % of the
    pixels. ``relearn_every`` 1 learns every frame, as :func:`refine_in_zone`; on the Pose2Sim
    views (silhouettes of cam01 91 ms per frame learning every frame, 63 at 3, 55 at 5)
    coverage and spill stay within a keypoint or two of learning every frame, as do different
    seeds, but at 5 cam02 fell to 1994 of 2100 keypoints (94.95 %) for two seeds of four, at 3
    it kept 1995-1998 for all four. Not cutting at all in two frames of three (the last mask
    kept in the zone, today's foreground added) was faster still but leaves a moved limb where
    it was: cam02 fell to 1990 (94.8 %) while cam03 rose to 1973 on stale masks; reusing the
    mask only where the foreground barely changed (under 5 % of its area) reused 1 box in 101 on
    cam03, whose window flicker changes 10-15 % of it from frame to frame.
    Other arguments: those of :func:`refine_in_zone`.
    ``learned`` and ``kept`` count the boxes cut each way.
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

    def reset(self) -> None:
        """Forget the kept colour models (a new scene or background)."""
        self._models = []

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
    max_side_px. Without ``models``: colour models learned from the seeds, 2 iterations, their
    k-means started from OpenCV's random generator reset to ``seed``; with (background, person)
    float64 (1, 65) GMMs: one cut with them frozen. Returns (uint8 (h, w) 255 = person at the
    crop's size, the background and person models used; both None when grabCut could not
    run)."""
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
