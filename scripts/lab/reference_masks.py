"""Silhouettes corrected by a reference: a diagnostic, never a method (it reads the answer).

On a real video whose subject has 2-D reference keypoints per frame (Pose2Sim's balancing trial,
``sequences.pose2sim.project_reference``), how much of the pose error comes from the silhouettes
and how much from the regressor? :class:`ReferenceMaskExtractor` wraps the tracker's extractor
and hands on each person's mask changed by the reference body (:func:`body_region`):

- ``cut``: the mask with everything off the body drawn from the keypoints removed (bones
  ``width`` x the keypoints' height thick, a generous body). The extractor's own outline is
  kept where it lies on the body; ghosts of the background model, shadows and blobs beside
  the body go. Parts of the body the extractor missed stay missing.
- ``drawn``: the drawn body itself in place of the extractor's people: a clean silhouette of
  the true pose, but a stick figure (lines, a torso quadrilateral, a disc for the head) unlike
  the training renders' skinned body.
- ``rendered`` (:class:`RenderedMaskExtractor`): the training renderer's own body fitted to the
  3-D reference (sequences.keypoint_fit) and rendered through the real camera: a silhouette of
  the true pose exactly like a training render.

If the regressor does well on these, the silhouettes are what limits it; if not even on
``rendered``, it is the regressor (poses its training did not cover).
"""
from __future__ import annotations

import cv2
import numpy as np

from tracker.video.silhouettes import PersonMask
from lab.silhouette_evaluation import BodyDrawing, body_region

MODES: tuple[str, ...] = ("cut", "drawn")     # ReferenceMaskExtractor's
#: Bone thickness as a fraction of the keypoints' height. cut: the silhouette evaluation's
#: generous body (0.14: ~0.22 m for a 1.6 m tall set of keypoints), so that the cut removes
#: only what is clearly off the body; drawn: ~0.13 m limbs.
DEFAULT_WIDTH = {"cut": 0.14, "drawn": 0.08}
_MIN_AREA_PX = 50               # a cut leaving less than this is no person


def person_from_mask(mask: np.ndarray, x: int, y: int) -> PersonMask | None:
    """The PersonMask of the set pixels of ``mask`` (bool (h, w)) whose top-left lies at
    (x, y) frame px, cropped to them; None when fewer than 50 pixels are set."""
    rows, cols = np.nonzero(mask)
    if len(rows) < _MIN_AREA_PX:
        return None
    r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
    crop = np.ascontiguousarray(mask[r0:r1, c0:c1])
    moments = cv2.moments(crop.astype(np.uint8), binaryImage=True)
    return PersonMask(crop, (int(x + c0), int(y + r0), int(c1 - c0), int(r1 - r0)),
                      (x + c0 + moments["m10"] / moments["m00"],
                       y + r0 + moments["m01"] / moments["m00"]), int(moments["m00"]))


def drawn_person(points_px: np.ndarray, body: BodyDrawing, width: float) -> PersonMask | None:
    """The body drawn from keypoints (K, 2) px as one PersonMask (see :func:`body_region`)."""
    p = np.asarray(points_px, np.float64)
    pad = int(np.ceil(width * float(np.ptp(p[:, 1])))) + 2
    x0, y0 = int(np.floor(p[:, 0].min())) - pad, int(np.floor(p[:, 1].min())) - pad
    x1, y1 = int(np.ceil(p[:, 0].max())) + pad + 1, int(np.ceil(p[:, 1].max())) + pad + 1
    region = body_region(p, body, (x0, y0, x1 - x0, y1 - y0), width)
    return person_from_mask(region, x0, y0)


class _WrappedExtractor:
    """An extractor wrapping the tracker's: its other attributes (prime, learn_zone,
    subtractor, ...) are reached through this one, and it still runs on every frame, so that
    its background model and zone stay as in a normal run. Frames are counted from 0 in the
    order they are given (tracker.run.track_video gives every frame of the video in order)."""

    def __init__(self, extractor):
        self.extractor = extractor
        self.frames_seen = 0

    def __getattr__(self, name):
        # Only called for attributes this object lacks.
        return getattr(self.__dict__["extractor"], name)

    def _extract(self, frame: np.ndarray) -> tuple[int, list[PersonMask]]:
        """(this frame's index, the wrapped extractor's people)."""
        index = self.frames_seen
        self.frames_seen += 1
        return index, self.extractor(frame)


class ReferenceMaskExtractor(_WrappedExtractor):
    """An extractor (frame -> list of PersonMask) whose people are changed by reference
    keypoints (module docstring). ``extractor``: the tracker's (its ``prime``, ``learn_zone``
    and other attributes are reached through this one); ``keypoints_px``: (T, K, 2) px of video
    frames ``frames`` (T,) int; ``body``: which keypoints make the body; ``mode``: "cut" or
    "drawn"; ``width``: bone thickness (fraction of the keypoints' height; default by mode).

    Frames are counted from 0 in the order they are given (tracker.run.track_video gives every
    frame of the video in order); a frame without keypoints gets no people.
    """

    def __init__(self, extractor, keypoints_px: np.ndarray, frames, body: BodyDrawing,
                 mode: str, width: float | None = None):
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        keypoints_px = np.asarray(keypoints_px, np.float64)
        frames = np.asarray(frames, np.int64).reshape(-1)
        if keypoints_px.ndim != 3 or keypoints_px.shape[2] != 2 or \
                len(keypoints_px) != len(frames):
            raise ValueError(f"keypoints_px must be (T, K, 2) for {len(frames)} frames, got "
                             f"{keypoints_px.shape}")
        super().__init__(extractor)
        self.body, self.mode = body, mode
        self.width = DEFAULT_WIDTH[mode] if width is None else float(width)
        self._keypoints = {int(f): p for f, p in zip(frames, keypoints_px)}

    def __call__(self, frame: np.ndarray) -> list[PersonMask]:
        index, people = self._extract(frame)
        points = self._keypoints.get(index)
        if points is None:
            return []
        if self.mode == "drawn":
            person = drawn_person(points, self.body, self.width)
            return [] if person is None else [person]
        out = []
        for person in people:
            x, y = person.bbox[:2]
            kept = person.mask & body_region(points, self.body, person.bbox, self.width)
            cut = person_from_mask(kept, x, y)
            if cut is not None:
                out.append(cut)
        return sorted(out, key=lambda p: -p.area)


class RenderedMaskExtractor(_WrappedExtractor):
    """An extractor whose one person per frame is a given silhouette: ``masks`` (T, H, W) bool
    in frame pixels for video frames ``frames`` (T,) int (e.g. the fitted body rendered through
    the view's camera). ``extractor``: the tracker's, still run on every frame (so that its
    background model and zone stay as in a normal run) and reached for its other attributes.
    Frames are counted from 0 in the order they are given; one without a mask (or with fewer
    than 50 pixels set) gets no people."""

    def __init__(self, extractor, masks: np.ndarray, frames):
        masks = np.asarray(masks, dtype=bool)
        frames = np.asarray(frames, np.int64).reshape(-1)
        if masks.ndim != 3 or len(masks) != len(frames):
            raise ValueError(f"masks must be (T, H, W) for {len(frames)} frames, got "
                             f"{masks.shape}")
        super().__init__(extractor)
        self._masks = {int(f): m for f, m in zip(frames, masks)}

    def __call__(self, frame: np.ndarray) -> list[PersonMask]:
        index, _ = self._extract(frame)
        mask = self._masks.get(index)
        person = None if mask is None else person_from_mask(mask, 0, 0)
        return [] if person is None else [person]
