"""Silhouettes on real frames (Pose2Sim, a person who never leaves the spot) and on rendered
scenes with a global brightness step and with two people passing close."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from sequences.video import textured_background
from tracker.tracks.association import Associator
from lab.silhouette_evaluation import (clip_extractor, legacy_associator,
                                                   legacy_extractor, silhouette_measures,
                                                   track_masks)
from tracker.video.silhouettes import SilhouetteExtractor

DATA = Path(__file__).parent / "data" / "pose2sim"
#: The order of the keypoints in cam01_16frames_keypoints.txt: the reference .trc's.
KEYPOINT_NAMES = ("RHip", "RKnee", "RAnkle", "RBigToe", "RSmallToe", "RHeel", "LHip", "LKnee",
                  "LAnkle", "LBigToe", "LSmallToe", "LHeel", "Neck", "Head", "Nose", "RShoulder",
                  "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist")


def balancing_frames() -> tuple[np.ndarray, np.ndarray]:
    """16 frames (16, 192, 108, 3) of Pose2Sim's cam01 and their keypoints (16, 21, 2) px."""
    mosaic = cv2.imread(str(DATA / "cam01_16frames.jpg"))
    frames = np.stack([mosaic[r * 192:(r + 1) * 192, c * 108:(c + 1) * 108]
                       for r in range(2) for c in range(8)])
    keypoints = np.loadtxt(DATA / "cam01_16frames_keypoints.txt").reshape(16, 21, 2)
    return frames, keypoints


def test_still_person_on_real_frames_is_one_person_shaped_mask():
    frames, keypoints = balancing_frames()
    tracked = track_masks(enumerate(frames), clip_extractor(frames))
    after = silhouette_measures(tracked, keypoints)
    assert after["coverage"] >= 0.9 and after["spill"] <= 0.15
    assert after["tracks"] == 1 and after["main_track_fraction"] == 1.0
    # The median background holds the person: holes, ghost limbs, pieces tracked apart.
    before = silhouette_measures(track_masks(enumerate(frames), legacy_extractor(frames),
                                             legacy_associator()), keypoints)
    assert before["coverage"] < 0.75 and before["tracks"] > 3


def person_scene(bg: np.ndarray, x: int, rng: np.random.Generator, gain: float = 1.0,
                 others: tuple[int, ...] = ()) -> np.ndarray:
    """The rendered scene bg (BGR) with a person-like figure at column x (and at each of
    others), lit by gain, with sensor noise."""
    frame = bg.copy()
    for cx, colour in [(x, (60, 90, 200))] + [(o, (200, 160, 60)) for o in others]:
        cv2.ellipse(frame, (cx, 140), (14, 55), 0, 0, 360, colour, -1)
        cv2.circle(frame, (cx, 72), 12, colour, -1)
    frame = cv2.multiply(frame, (gain, gain, gain, 0.0))
    return cv2.add(frame, rng.integers(0, 6, frame.shape, dtype=np.uint8))


def test_global_brightness_step_of_30_percent_gives_no_false_blob():
    rng = np.random.default_rng(0)
    bg = cv2.cvtColor(textured_background((240, 320), seed=3), cv2.COLOR_RGB2BGR)
    walk = [person_scene(bg, 40 + 6 * t, rng, gain=1.0 if t < 20 else 1.3) for t in range(40)]
    extractor = SilhouetteExtractor()
    extractor.prime(walk[:20:2])
    for t, frame in enumerate(walk):
        people = extractor(frame)
        assert len(people) == 1, f"frame {t}: {len(people)} blobs"
        assert abs(people[0].centroid[0] - (40 + 6 * t)) < 6
        assert people[0].area < 4 * 110 * 28


def test_two_people_passing_close_keep_their_identities():
    rng = np.random.default_rng(1)
    bg = cv2.cvtColor(textured_background((240, 320), seed=4), cv2.COLOR_RGB2BGR)
    # Blue walks right, yellow left; at their closest they pass 2 px apart.
    scenes = [person_scene(bg, 40 + 6 * t, rng, others=(280 - 6 * t,)) for t in range(40)]
    extractor, associator = SilhouetteExtractor(), Associator()
    extractor.prime(scenes[::4])
    ids = {}
    for t, frame in enumerate(scenes):
        for track_id, person in associator.update(extractor(frame)):
            blue = person.centroid[0] < 160 if t < 20 else person.centroid[0] > 160
            ids.setdefault("blue" if blue else "yellow", []).append((t, track_id))
    for name in ("blue", "yellow"):
        before = {i for t, i in ids[name] if t < 15}
        after = {i for t, i in ids[name] if t >= 25}
        assert len(before) == 1 and before == after, f"{name}: {ids[name]}"


def union_mask(people, shape: tuple[int, int]) -> np.ndarray:
    """bool (H, W): every PersonMask of one frame pasted into the frame."""
    out = np.zeros(shape, bool)
    for person in people:
        x, y, w, h = person.bbox
        out[y:y + h, x:x + w] |= person.mask
    return out


@pytest.mark.parametrize("trust, tolerance", [(True, 0.05), (False, 0.065)],
                         ids=["zone-foreground-sure", "zone-foreground-colour"])
def test_kept_colour_models_cut_real_frames_as_learning_every_frame_does(trust, tolerance):
    # With colour deciding in the zone too, kept models drift more (6.2 % of a mask at most on
    # these frames, 2026-12-02): one reason that rule is not the default.
    frames, keypoints = balancing_frames()
    every = SilhouetteExtractor(refine_relearn_every=1, trust_zone_foreground=trust)
    kept = SilhouetteExtractor(trust_zone_foreground=trust)
    every.prime(frames)
    kept.prime(frames)
    for t, frame in enumerate(frames):
        a, b = union_mask(every(frame), frame.shape[:2]), union_mask(kept(frame), frame.shape[:2])
        assert np.count_nonzero(a ^ b) <= tolerance * np.count_nonzero(a), f"frame {t}"
    # The models are learned in one frame of three; grabCut still cuts every frame.
    assert every.refiner.kept == 0 and every.refiner.learned >= len(frames)
    assert kept.refiner.learned <= every.refiner.learned // 2
    assert kept.refiner.learned + kept.refiner.kept == every.refiner.learned


def test_real_frames_give_the_same_masks_whatever_ran_before():
    frames, _ = balancing_frames()

    def masks() -> list[np.ndarray]:
        extractor = SilhouetteExtractor(refine_relearn_every=1)
        extractor.prime(frames)
        return [union_mask(extractor(f), f.shape[:2]) for f in frames]

    first = masks()
    cv2.setRNGSeed(12345)                 # another user of OpenCV's generator ran in between
    cv2.kmeans(np.random.default_rng(0).random((50, 3), dtype=np.float32), 4, None,
               (cv2.TERM_CRITERIA_MAX_ITER, 5, 0), 1, cv2.KMEANS_RANDOM_CENTERS)
    assert all(np.array_equal(a, b) for a, b in zip(first, masks()))


def test_off_body_is_the_share_of_the_mask_away_from_the_keypoints_body():
    from lab.silhouette_evaluation import BodyDrawing, body_region, off_body
    from tracker.video.silhouettes import PersonMask
    # A torso square, a head above it and one leg below: keypoints 100 px tall.
    points = np.array([[40, 30], [60, 30], [60, 60], [40, 60], [50, 10], [45, 110]], float)
    body = BodyDrawing(torso=(0, 1, 2, 3), head=4, bones=((3, 5),))
    box = (0, 0, 120, 130)
    region = body_region(points, body, box, width=0.1)          # lines and head 10 px
    assert region[45, 50] and region[10, 50] and region[100, 46] and not region[45, 100]
    person = PersonMask(region.copy(), box, (50.0, 50.0), int(region.sum()))
    assert off_body(person, points, body, width=0.1) == 0.0
    blob = region.copy()
    blob[40:60, 90:110] = True                                  # background taken for person
    person = PersonMask(blob, box, (60.0, 50.0), int(blob.sum()))
    assert off_body(person, points, body, width=0.1) == pytest.approx(400 / blob.sum())
    named = BodyDrawing.from_names(["a", "b", "c", "d", "head", "foot"], ("a", "b", "c", "d"),
                                   "head", (("d", "foot"),))
    assert named == body
    with pytest.raises(ValueError, match="'toe'"):
        BodyDrawing.from_names(["a", "b", "c", "d", "head"], ("a", "b", "c", "d"), "head",
                               (("d", "toe"),))
    # The drawing does not depend on where the box cuts it.
    small = body_region(points, body, (40, 50, 30, 40), width=0.1)
    assert np.array_equal(small, region[50:90, 40:70])


def test_letting_colour_decide_in_the_zone_takes_less_background_for_the_person():
    from sequences.pose2sim import BODY_BONES, BODY_HEAD, BODY_TORSO
    from lab.silhouette_evaluation import BodyDrawing, colour_zone_extractor
    body = BodyDrawing.from_names(KEYPOINT_NAMES, BODY_TORSO, BODY_HEAD, BODY_BONES)
    frames, keypoints = balancing_frames()
    sure = silhouette_measures(track_masks(enumerate(frames), clip_extractor(frames)),
                               keypoints, body=body)
    colour = silhouette_measures(track_masks(enumerate(frames), colour_zone_extractor(frames)),
                                 keypoints, body=body)
    # The sure rule (track's default until 2026-12-04) keeps the median's ghosts beside the
    # torso: over a fifth of the mask.
    assert sure["off_body"] > 0.2
    assert colour["off_body"] < 0.75 * sure["off_body"]
    assert colour["coverage"] >= 0.88 and colour["main_track_fraction"] == 1.0
    # Its known cost: the floor blob the zone had glued to the body is a track of its own.
    assert sure["tracks"] == 1 and colour["tracks"] <= 2


@pytest.mark.parametrize("trust", [True, False])
def test_the_tracker_builds_its_extractor_with_the_zone_setting(trust):
    from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
    from tracker import PoseTracker, TrackerSettings
    model = load_pose_model(DEFAULT_MODEL_PATH)
    settings = TrackerSettings(trust_zone_foreground=trust)
    tracker = PoseTracker(model, 30.0, settings)
    assert tracker.extractor.trust_zone_foreground is trust
    # A grey scene rebuilds the extractor without shadow detection: the setting stays.
    before = tracker.extractor
    tracker.prime(np.full((120, 160, 3), 90, np.uint8))
    assert tracker.extractor is not before
    assert not tracker.extractor.subtractor._mog2_options["detectShadows"]
    assert tracker.extractor.trust_zone_foreground is trust
