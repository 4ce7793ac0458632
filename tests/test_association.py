"""Track association: ids persist across frames, crossings, misses and size changes."""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import pytest

from tracker.tracks.association import AssociationError, Associator
from tracker.video.silhouettes import SilhouetteExtractor


@dataclass
class Det:
    centroid: tuple[float, float]
    area: int = 10000


def ids_of(pairs) -> list[int]:
    return [track_id for track_id, _ in pairs]


def test_one_walker_keeps_one_id():
    associator = Associator()
    ids = [ids_of(associator.update([Det((100 + 5 * t, 200))])) for t in range(50)]
    assert ids == [[0]] * 50


def test_pairs_come_back_in_detection_order():
    associator = Associator()
    associator.update([Det((100, 100)), Det((400, 100))])
    left, right = Det((402, 101)), Det((103, 99))
    assert associator.update([left, right]) == [(1, left), (0, right)]


def test_crossing_people_keep_their_ids_through_a_merge():
    associator = Associator()
    history, merged_frames = {0: [], 1: []}, set()
    for t in range(60):
        a, b = 100.0 + 6 * t, 460.0 - 6 * t
        if abs(a - b) < 90:  # touching: background subtraction sees one blob
            detections = [Det(((a + b) / 2, 200), 20000)]
            merged_frames.add(t)
        else:
            detections = [Det((a, 200)), Det((b, 205))]
        for track_id, det in associator.update(detections):
            history.setdefault(track_id, []).append((t, det.centroid[0]))
    # Before the crossing 0 is on the left; after it, 0 must have carried on to the right.
    assert history[0][0][1] < 200 and history[0][-1][1] > 400
    assert history[1][0][1] > 400 and history[1][-1][1] < 200
    assert len(history[0]) == len(history[1]) == 60 - len(merged_frames)
    # The two-person blob is neither person: it may only have a short-lived id of its own.
    others = [t for track_id, points in history.items() if track_id > 1 for t, _ in points]
    assert set(others) <= merged_frames


def test_far_detection_starts_a_new_track():
    associator = Associator()
    associator.update([Det((100, 100))])
    assert ids_of(associator.update([Det((100, 100)), Det((500, 400))])) == [0, 1]


def test_large_size_change_is_not_the_same_person():
    associator = Associator(max_area_ratio=1.8)
    associator.update([Det((100, 100), 10000)])
    assert ids_of(associator.update([Det((102, 100), 30000)])) == [1]


def test_short_miss_keeps_id_long_absence_gets_new_id():
    associator = Associator(max_missed=5)
    for t in range(10):
        associator.update([Det((100 + 4 * t, 100))])
    for _ in range(3):
        assert associator.update([]) == []
    # Coasting at 4 px/frame over the 3 missed frames, the walker is expected at x = 152.
    assert ids_of(associator.update([Det((152, 100))])) == [0]
    for _ in range(6):
        associator.update([])
    assert associator.tracks == []
    assert ids_of(associator.update([Det((180, 100))])) == [1]


def test_bad_settings_and_detections_are_refused():
    with pytest.raises(AssociationError):
        Associator(max_area_ratio=0.5)
    with pytest.raises(AssociationError, match="positive areas"):
        Associator().update([Det((1.0, 2.0), 0)])


def test_silhouettes_of_two_crossing_people_keep_ids():
    rng = np.random.default_rng(0)
    bg = cv2.GaussianBlur(rng.integers(0, 256, (120, 200, 3), dtype=np.uint8), (0, 0), 2)
    extractor, associator = SilhouetteExtractor(warmup_frames=5), Associator()
    first_seen, last_seen = {}, {}
    for t in range(5 + 36):
        frame = bg.copy()
        if t >= 5:  # the people walk in after the background warm-up
            walked = 4 * (t - 5)
            for x, colour in ((30 + walked, (40, 200, 40)), (170 - walked, (200, 40, 200))):
                cv2.ellipse(frame, (x, 62), (9, 40), 0, 0, 360, colour, -1)
        frame = cv2.add(frame, rng.integers(0, 8, frame.shape, dtype=np.uint8))
        for track_id, person in associator.update(extractor(frame)):
            first_seen.setdefault(track_id, person.centroid[0])
            last_seen[track_id] = person.centroid[0]
    left, right = sorted((0, 1), key=lambda track_id: first_seen[track_id])
    assert first_seen[left] < 50 and last_seen[left] > 150
    assert first_seen[right] > 150 and last_seen[right] < 50


@dataclass
class Box:
    centroid: tuple[float, float]
    area: int
    bbox: tuple[int, int, int, int]


def test_silhouette_that_grows_in_place_keeps_its_id():
    # A standing person whose legs the extractor finds only from frame 5 on: the area
    # triples and the centroid drops, but the box still holds the old one.
    associator = Associator(max_area_ratio=1.8)
    upper = Box((100, 80), 2000, (80, 40, 40, 80))
    whole = Box((100, 120), 6000, (80, 40, 40, 160))
    ids = [ids_of(associator.update([upper if t < 5 else whole])) for t in range(10)]
    assert ids == [[0]] * 10
    # A blob of that size elsewhere is someone else.
    elsewhere = Box((400, 120), 18000, (340, 40, 120, 160))
    assert ids_of(associator.update([whole, elsewhere])) == [0, 1]


def test_short_lived_small_blob_beside_a_person_gets_no_track():
    associator = Associator(min_hits=3)
    person = Box((100, 120), 6000, (80, 40, 40, 160))
    blob = Box((160, 190), 300, (150, 180, 20, 20))      # light on the floor at the feet
    seen = [ids_of(associator.update([person, blob] if t in (3, 4) else [person]))
            for t in range(8)]
    assert seen == [[0]] * 8
    # A small blob that stays three frames running is something: it becomes a track.
    seen = [ids_of(associator.update([person, blob])) for _ in range(4)]
    assert seen == [[0], [0], [0, 1], [0, 1]]


def test_first_people_and_people_as_big_get_an_id_at_once():
    associator = Associator(min_hits=3)
    assert ids_of(associator.update([Box((50, 50), 300, (40, 40, 20, 20))])) == [0]
    big = Box((300, 120), 6000, (280, 40, 40, 160))
    assert ids_of(associator.update([Box((51, 50), 300, (41, 40, 20, 20)), big])) == [0, 1]
