"""lab.reference_masks: silhouettes cut to, or replaced by, a body drawn from
reference keypoints (the Pose2Sim diagnostic), on hand-made frames and keypoints."""
from __future__ import annotations

import numpy as np
import pytest

from lab.reference_masks import (ReferenceMaskExtractor, RenderedMaskExtractor,
                                             drawn_person, person_from_mask)
from lab.silhouette_evaluation import BodyDrawing
from tracker.video.silhouettes import PersonMask

# A stick person 100 px tall standing at x = 60: keypoints head, neck, hips, knees, ankles.
_NAMES = ("Head", "Neck", "LHip", "RHip", "LKnee", "RKnee", "LAnkle", "RAnkle")
_POINTS = np.array([[60, 20], [60, 35], [65, 70], [55, 70], [66, 95], [54, 95], [67, 120],
                    [53, 120]], float)
_BODY = BodyDrawing.from_names(_NAMES, ("Neck", "LHip", "RHip"), "Head",
                               (("Neck", "Head"), ("LHip", "LKnee"), ("LKnee", "LAnkle"),
                                ("RHip", "RKnee"), ("RKnee", "RAnkle")))


class _Extractor:
    """Stand-in extractor: every frame, one person made of the body plus a blob far to its
    right (a ghost), as a full-frame mask; counts prime calls."""

    def __init__(self):
        self.primed = 0
        self.calls = 0

    def prime(self, background, frame_size=None):
        self.primed += 1

    def __call__(self, frame):
        self.calls += 1
        mask = np.zeros(frame.shape[:2], bool)
        mask[15:125, 45:75] = True          # the body, roughly
        mask[60:90, 75:140] = True          # a ghost attached to its side
        return [person_from_mask(mask, 0, 0)]


def test_person_from_mask_crops_and_places_the_mask():
    mask = np.zeros((50, 60), bool)
    mask[10:30, 20:25] = True
    person = person_from_mask(mask, 100, 200)
    assert person.bbox == (120, 210, 5, 20) and person.area == 100
    assert person.centroid == pytest.approx((122.0, 219.5))
    assert person_from_mask(mask[:12], 0, 0) is None          # 10 px: no person


def test_the_cut_removes_what_lies_off_the_body_and_keeps_the_body():
    frame = np.zeros((160, 160, 3), np.uint8)
    wrapped = ReferenceMaskExtractor(_Extractor(), _POINTS[None], [0], _BODY, "cut")
    (person,) = wrapped(frame)
    x, y, w, h = person.bbox
    full = np.zeros((160, 160), bool)
    full[y:y + h, x:x + w] = person.mask
    assert not full[60:90, 100:140].any()                     # the ghost is gone
    assert full[20:65, 59:62].all() and full[75:115, 64:68].all()   # head, torso, a leg stay
    assert person.area < 0.6 * (110 * 30 + 30 * 65)


def test_drawn_people_are_the_drawing_and_frames_without_keypoints_have_none():
    frame = np.zeros((160, 160, 3), np.uint8)
    inner = _Extractor()
    wrapped = ReferenceMaskExtractor(inner, np.stack([_POINTS, _POINTS + (10, 0)]), [1, 2],
                                     _BODY, "drawn")
    assert wrapped(frame) == []                               # frame 0: no keypoints
    first, = wrapped(frame)
    second, = wrapped(frame)
    assert inner.calls == 3                                   # the extractor still runs
    assert second.bbox[0] == first.bbox[0] + 10 and second.area == first.area
    x, y, w, h = first.bbox
    assert x <= 53 and x + w >= 67 and y <= 20 and y + h >= 120
    again = drawn_person(_POINTS, _BODY, 0.08)
    assert again.bbox == first.bbox and np.array_equal(again.mask, first.mask)


def test_the_wrapped_extractors_methods_are_reached_and_bad_settings_refused():
    inner = _Extractor()
    wrapped = ReferenceMaskExtractor(inner, _POINTS[None], [0], _BODY, "cut")
    wrapped.prime(np.zeros((4, 4, 3), np.uint8))
    assert inner.primed == 1
    with pytest.raises(ValueError, match="mode"):
        ReferenceMaskExtractor(inner, _POINTS[None], [0], _BODY, "perfect")
    with pytest.raises(ValueError, match="keypoints_px"):
        ReferenceMaskExtractor(inner, _POINTS, [0], _BODY, "cut")
    assert isinstance(person_from_mask(np.ones((10, 10), bool), 0, 0), PersonMask)


def test_rendered_people_are_the_given_masks_where_there_are_any():
    frame = np.zeros((160, 160, 3), np.uint8)
    inner = _Extractor()
    masks = np.zeros((2, 160, 160), bool)
    masks[0, 30:130, 70:90] = True
    masks[1, 40:42, 10:12] = True                             # 4 px: no person
    wrapped = RenderedMaskExtractor(inner, masks, [1, 2])
    assert wrapped(frame) == []                               # frame 0: no mask
    (person,) = wrapped(frame)
    assert person.bbox == (70, 30, 20, 100) and person.area == 2000
    assert wrapped(frame) == [] and wrapped(frame) == []      # too small; past the end
    assert inner.calls == 4                                   # the extractor still runs
    wrapped.prime(np.zeros((4, 4, 3), np.uint8))
    assert inner.primed == 1
    with pytest.raises(ValueError, match="masks"):
        RenderedMaskExtractor(inner, masks[0], [1])
