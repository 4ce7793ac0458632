"""People whose silhouettes touch: the tracks' remembered shapes split the blob, so each keeps
its own silhouette (and so a pose), its id, and a single person is never split."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from tracker.tracks.association import Associator
from tracker.video.blob_split import Shape, split_blob
from lab.silhouette_evaluation import FramePeople, own_track_frames
from tracker.video.silhouettes import PersonMask

FRAME = (240, 480)                      # (height, width) px


def _drawn(x: float, arms_out: bool = False, stride: float = 0.0) -> np.ndarray:
    """A drawn person (FRAME bool) 160 px tall standing at column x: head, torso, arms and
    legs (legs apart by ``stride`` x 20 px)."""
    canvas = np.zeros(FRAME, np.uint8)
    cx = int(round(x))
    cv2.circle(canvas, (cx, 50), 13, 1, -1)                                 # head
    cv2.ellipse(canvas, (cx, 105), (20, 42), 0, 0, 360, 1, -1)             # torso
    hand_y = 85 if arms_out else 140
    for side in (-1, 1):
        cv2.line(canvas, (cx + side * 16, 75), (cx + side * (48 if arms_out else 24), hand_y),
                 1, 8)                                                      # arms
        cv2.line(canvas, (cx + side * 8, 140), (cx + side * int(8 + 20 * stride), 210), 1,
                 11)                                                        # legs
    return canvas > 0


def _person(mask: np.ndarray) -> PersonMask:
    """A PersonMask of a frame-sized bool mask."""
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    y0, y1, x0, x1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    ys, xs = np.nonzero(mask)
    return PersonMask(mask[y0:y1, x0:x1].copy(), (int(x0), int(y0), int(x1 - x0),
                                                   int(y1 - y0)),
                      (float(xs.mean()), float(ys.mean())), int(mask.sum()))


def _frame_mask(person: PersonMask) -> np.ndarray:
    out = np.zeros(FRAME, bool)
    x, y, w, h = person.bbox
    out[y:y + h, x:x + w] = person.mask
    return out


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def _detections(masks: list[np.ndarray]) -> list[PersonMask]:
    """The people as background subtraction sees them: touching masks are one blob."""
    union = np.any(masks, axis=0).astype(np.uint8)
    count, labels = cv2.connectedComponents(union, connectivity=8)
    return [_person(labels == k) for k in range(1, count)]


def _walk(frames: int = 70):
    """Two people walking towards each other 2 px a frame, the right one with its arms out:
    per frame their true masks; they touch from frame 34 on and cross at frame 52.5."""
    for t in range(frames):
        a, b = 120.0 + 2 * t, 330.0 - 2 * t
        yield t, [_drawn(a, stride=(t % 10) / 10), _drawn(b, arms_out=True)]


def test_touching_people_get_one_silhouette_each_close_to_their_own_and_keep_their_ids():
    # Track 0 starts on the left person (the first detection, largest first: equal areas).
    associator = Associator()
    touching, ious, whole = 0, [], []
    ids_apart: dict[int, set] = {0: set(), 1: set()}
    for t, truth in _walk():
        detections = _detections(truth)
        pairs = associator.update(detections)
        if len(detections) == 1:
            touching += 1
            assert sorted(i for i, _ in pairs) == [0, 1], f"frame {t}: {pairs}"
            blob = _frame_mask(detections[0])
            parts = {i: _frame_mask(p) for i, p in pairs}
            assert not (parts[0] & parts[1]).any() and ((parts[0] | parts[1]) == blob).all()
            own = {0: truth[0], 1: truth[1]}          # track 0 is the one who began left
            for i in (0, 1):
                assert _iou(parts[i], own[i]) > _iou(parts[i], own[1 - i])
            overlap = (truth[0] & truth[1]).sum() / min(m.sum() for m in truth)
            if overlap < 0.3:           # touching, not one hidden behind the other
                ious += [_iou(parts[i], own[i]) for i in (0, 1)]
                whole += [_iou(blob, own[i]) for i in (0, 1)]
        else:
            for track_id, person in pairs:
                left = person.centroid[0] < 225       # they cross at t = 52.5
                ids_apart[0 if left == (t < 52) else 1].add(track_id)
    assert touching >= 30 and len(ious) >= 40
    assert min(ious) >= 0.75 and np.mean(ious) >= 0.9
    assert np.mean(ious) > np.mean(whole) + 0.3         # far better than the blob itself
    assert ids_apart == {0: {0}, 1: {1}}                # each person one id, before and after


def test_a_single_person_is_never_split():
    associator = Associator()
    for t in range(60):
        person = _person(_drawn(100.0 + 3 * t, arms_out=t % 20 >= 10, stride=(t % 8) / 8))
        pairs = associator.update([person])
        assert [p for _, p in pairs] == [person]
        assert {i for i, _ in pairs} == {0}


def test_split_blob_gives_each_shape_the_pixels_deepest_inside_it():
    left, right = _drawn(200.0), _drawn(236.0, arms_out=True)
    blob = _person(left | right)
    parts = split_blob(blob, [Shape(_person(left).mask, _person(left).bbox),
                              Shape(_person(right).mask, _person(right).bbox)])
    assert _iou(_frame_mask(parts[0]), left) >= 0.8
    assert _iou(_frame_mask(parts[1]), right) >= 0.8


def test_a_member_hidden_behind_the_other_gets_no_fragment():
    front, behind = _drawn(200.0, arms_out=True), _drawn(202.0)
    blob = _person(front | behind)
    small = _person(_drawn(202.0))
    # The one behind is drawn as a narrow sliver of its own shape: nearly all of the blob is
    # the front person's shape, so the member behind has less than min_share of its own.
    sliver = np.zeros_like(small.mask)
    sliver[:, :3] = small.mask[:, :3]
    parts = split_blob(blob, [Shape(_person(front).mask, _person(front).bbox),
                              Shape(sliver, (small.bbox[0] - 60, *small.bbox[1:]))])
    assert parts[0] is not None and parts[1] is None


def test_split_blob_needs_two_shapes():
    person = _person(_drawn(200.0))
    with pytest.raises(ValueError, match="two or more shapes"):
        split_blob(person, [Shape(person.mask, person.bbox)])


def test_own_track_needs_the_keypoints_covered_and_little_spill():
    keypoints = np.array([[[200.0, 40.0], [200.0, 105.0], [190.0, 205.0], [210.0, 205.0]]])
    alone = _person(_drawn(200.0))
    joined = _person(_drawn(200.0) | _drawn(236.0, arms_out=True) | _drawn(272.0))
    elsewhere = _person(_drawn(400.0))
    assert own_track_frames([FramePeople(0, [(0, alone)])], keypoints).tolist() == [True]
    assert own_track_frames([FramePeople(0, [(0, joined)])], keypoints).tolist() == [False]
    assert own_track_frames([FramePeople(0, [(0, elsewhere)])], keypoints).tolist() == [False]
    assert own_track_frames([FramePeople(0, [(3, elsewhere), (5, alone)])],
                            keypoints).tolist() == [True]


@pytest.mark.slow          # loads the shipped model: ~20 s
def test_the_tracker_gives_both_touching_people_a_pose():
    # As the frame worker hands them over: the blob described, its parts not (they are made
    # by the association, in the main process).
    from regressor.pose_model import load_pose_model
    from tracker import PoseTracker, TrackerSettings

    tracker = PoseTracker(load_pose_model(), 30.0, TrackerSettings(keep_history=False))
    tracker._set_frame_shape(FRAME)
    posed_touching = []
    for t, truth in _walk():
        people = _detections(truth)
        poses = tracker.track_frames([(t, t / 30.0, people,
                                       [tracker.describe(p) for p in people])])[0][0]
        if len(people) == 1:
            posed_touching.append(sorted(p.track_id for p in poses))
    assert len(posed_touching) >= 20 and all(ids == [0, 1] for ids in posed_touching)


def test_found_touching_counts_each_person_under_their_own_id_while_the_boxes_overlap():
    from lab.crossings import identity_measures

    # Two people 100 px tall: apart in frames 0-1 and 4-5, boxes overlapping in 2-3.
    xs = np.array([[50, 250], [80, 220], [130, 170], [170, 130], [220, 80], [250, 50]], float)
    centroids = np.stack([xs, np.full_like(xs, 100.0)], axis=2)                # (6, 2, 2)
    boxes = np.concatenate([centroids - [30, 50], np.full((6, 2, 2), [60, 100])], axis=2)

    def reported(touching):
        apart = {t: [(7, tuple(centroids[t, 0])), (9, tuple(centroids[t, 1]))]
                 for t in (0, 1, 4, 5)}
        return [apart.get(t) or touching(t) for t in range(6)]

    both = identity_measures(reported(lambda t: [(7, tuple(centroids[t, 0])),
                                                 (9, tuple(centroids[t, 1]))]),
                             centroids, boxes)
    one = identity_measures(reported(lambda t: [(7, tuple(centroids[t, 0]))]), centroids, boxes)
    swapped = identity_measures(reported(lambda t: [(9, tuple(centroids[t, 0])),
                                                    (7, tuple(centroids[t, 1]))]),
                                centroids, boxes)
    nobody = identity_measures(reported(lambda t: []), centroids, boxes)
    assert (both["found_touching"], one["found_touching"], swapped["found_touching"],
            nobody["found_touching"]) == (1.0, 0.5, 0.0, 0.0)
    assert both["switches"] == 0 and both["crossings"] == 1
