"""Silhouettes: background subtraction, cleaning, per-person masks on synthetic scenes."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from tracker.video.silhouettes import (BackgroundSubtractor, PersonMask, ExtractionError,
                                        SilhouetteExtractor, clean_mask, median_background,
                                        person_masks)
from tracker.video.zone import ZoneRefiner, refine_in_zone, _unless_collapsed, _zone_labels


def background(width: int, height: int, seed: int = 0) -> np.ndarray:
    """A static textured scene, BGR uint8 (height, width, 3)."""
    rng = np.random.default_rng(seed)
    return cv2.GaussianBlur(rng.integers(0, 256, (height, width, 3), dtype=np.uint8), (0, 0), 3)


def draw_person(image: np.ndarray, centre: tuple[int, int], height: int,
                colour=(40, 190, 70)) -> None:
    """A person-like shape (ellipse body and round head) of about ``height`` px, in place."""
    x, y = centre
    cv2.ellipse(image, (x, y), (height // 8, height * 3 // 8), 0, 0, 360, colour, -1)
    cv2.circle(image, (x, y - height * 7 // 16), height // 9, colour, -1)


def scene(bg: np.ndarray, centres: list[tuple[int, int]], height: int,
          rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(noisy frame BGR uint8, truth mask bool) with a person at each centre."""
    frame, truth = bg.copy(), np.zeros(bg.shape[:2], np.uint8)
    for centre in centres:
        draw_person(frame, centre, height)
        draw_person(truth, centre, height, colour=255)
    noise = rng.integers(0, 10, bg.shape, dtype=np.uint8)
    return cv2.add(frame, noise), truth > 0


def iou(person: PersonMask, truth: np.ndarray) -> float:
    x, y, w, h = person.bbox
    found = np.zeros_like(truth)
    found[y:y + h, x:x + w] = person.mask
    return np.count_nonzero(found & truth) / np.count_nonzero(found | truth)


def warm_up(extractor: SilhouetteExtractor, bg: np.ndarray, rng: np.random.Generator) -> None:
    for _ in range(extractor.subtractor.warmup_frames):
        assert extractor(scene(bg, [], 0, rng)[0]) == []


def test_moving_person_found_at_frame_resolution():
    rng = np.random.default_rng(1)
    bg = background(640, 480)
    extractor = SilhouetteExtractor()  # works at 320 px, masks come back at 640
    warm_up(extractor, bg, rng)
    for i in range(12):
        frame, truth = scene(bg, [(150 + 12 * i, 260)], 240, rng)
        people = extractor(frame)
        assert len(people) == 1
        person = people[0]
        assert iou(person, truth) > 0.93
        ys, xs = np.nonzero(truth)
        assert np.hypot(person.centroid[0] - xs.mean(), person.centroid[1] - ys.mean()) < 2.0
        assert person.area == np.count_nonzero(person.mask)
        assert person.mask.shape == (person.bbox[3], person.bbox[2]) and person.mask.dtype == bool


def test_two_people_give_two_masks_largest_first():
    rng = np.random.default_rng(2)
    bg = background(320, 240)
    extractor = SilhouetteExtractor()
    warm_up(extractor, bg, rng)
    frame = bg.copy()
    draw_person(frame, (80, 130), 160)
    draw_person(frame, (240, 150), 110)
    people = extractor(frame)
    assert len(people) == 2
    assert people[0].area > people[1].area
    assert abs(people[0].centroid[0] - 80) < 3 and abs(people[1].centroid[0] - 240) < 3


def test_a_person_60_px_tall_at_640x480_is_found_by_default_not_by_the_former_gate():
    rng = np.random.default_rng(11)
    bg = background(640, 480)
    found = {}
    for name, extractor in (("default", SilhouetteExtractor()),
                            ("former", SilhouetteExtractor(min_area_fraction=0.003))):
        warm_up(extractor, bg, rng)
        found[name] = [extractor(scene(bg, [(200 + 10 * i, 300)], 60, rng)[0])
                       for i in range(5)]
    assert all(len(people) == 1 for people in found["default"])
    assert all(people[0].bbox[3] >= 50 for people in found["default"])
    assert all(people == [] for people in found["former"])


def test_empty_scene_and_small_clutter_give_no_people():
    rng = np.random.default_rng(3)
    bg = background(320, 240)
    extractor = SilhouetteExtractor(min_area_fraction=0.003)
    warm_up(extractor, bg, rng)
    for _ in range(5):
        assert extractor(scene(bg, [], 0, rng)[0]) == []
    frame = scene(bg, [], 0, rng)[0]
    cv2.circle(frame, (100, 100), 4, (255, 0, 255), -1)  # ~50 px, below 0.3 % of 76800
    assert extractor(frame) == []
    default = SilhouetteExtractor()                       # 0.15 %: 115 px at 320x240
    warm_up(default, bg, rng)
    assert default(frame) == []


def test_shadow_is_not_foreground():
    rng = np.random.default_rng(4)
    bg = background(320, 240)
    extractor = SilhouetteExtractor()
    warm_up(extractor, bg, rng)
    frame, truth = scene(bg, [(100, 130)], 160, rng)
    shadow = np.zeros(bg.shape[:2], np.uint8)
    cv2.ellipse(shadow, (220, 200), (60, 20), 0, 0, 360, 255, -1)
    frame[shadow > 0] = (frame[shadow > 0] * 0.7).astype(np.uint8)
    people = extractor(frame)
    assert len(people) == 1 and iou(people[0], truth) > 0.9


def test_warmup_frames_return_nothing_then_people():
    rng = np.random.default_rng(5)
    bg = background(160, 120)
    extractor = SilhouetteExtractor(warmup_frames=4)
    frames = [scene(bg, [(80, 60)], 80, rng)[0] for _ in range(6)]
    results = [extractor(f) for f in frames[:4]]
    assert results == [[], [], [], []]
    assert not BackgroundSubtractor(warmup_frames=4).ready


def test_still_person_kept_for_a_hundred_frames():
    rng = np.random.default_rng(6)
    bg = background(160, 120)
    extractor = SilhouetteExtractor()
    warm_up(extractor, bg, rng)
    areas = [sum(p.area for p in extractor(scene(bg, [(80, 65)], 90, rng)[0]))
             for _ in range(100)]
    assert min(areas) > 0.9 * areas[0] > 0


def test_priming_with_median_background_finds_people_from_first_frame():
    rng = np.random.default_rng(7)
    bg = background(320, 240)
    shots = [scene(bg, [(40 + 8 * i, 130)], 150, rng) for i in range(30)]
    primed = SilhouetteExtractor()
    primed.prime(median_background([frame for frame, _ in shots[::3]]))
    assert primed.subtractor.ready
    for frame, truth in shots:
        people = primed(frame)
        assert len(people) == 1 and iou(people[0], truth) > 0.9


def test_small_holes_filled_large_holes_kept():
    mask = np.zeros((100, 100), np.uint8)
    mask[10:90, 10:90] = 255
    mask[20:23, 20:23] = 0  # 9 px hole: a subtraction dropout
    mask[40:70, 40:70] = 0  # 900 px hole: real background (e.g. between arm and torso)
    (person,) = person_masks(mask, (100, 100), min_area_fraction=0.01, max_hole_fraction=0.01,
                             max_area_fraction=1.0)      # 64 % of this small image
    assert person.bbox == (10, 10, 80, 80)
    assert person.mask[10:13, 10:13].all()
    assert not person.mask[30:60, 30:60].any()
    assert person.area == 80 * 80 - 900


def test_component_reproduced_exactly_at_equal_resolution():
    rng = np.random.default_rng(8)
    blobs = cv2.GaussianBlur(rng.random((60, 80)).astype(np.float32), (0, 0), 2.5) > 0.5
    mask = blobs.astype(np.uint8) * 255
    count, labels = cv2.connectedComponents(mask, connectivity=8)
    people = person_masks(mask, (80, 60), min_area_fraction=0.0, max_hole_fraction=0.0,
                          merge_fragments=False)
    assert len(people) == count - 1
    for person in people:
        x, y, w, h = person.bbox
        label = labels[y:y + h, x:x + w][person.mask][0]
        assert np.array_equal(labels[y:y + h, x:x + w] == label, person.mask)


def test_masks_scaled_up_to_frame_size():
    mask = np.zeros((60, 80), np.uint8)
    mask[10:40, 20:30] = 255
    (person,) = person_masks(mask, (320, 240), min_area_fraction=0.01)
    assert person.bbox == (80, 40, 40, 120)
    assert person.area == 40 * 120
    assert person.centroid == pytest.approx((99.5, 99.5))


def test_clean_mask_drops_specks_and_joins_gaps():
    mask = np.zeros((50, 50), np.uint8)
    mask[5, 5] = 255
    mask[10:40, 10:24] = 255
    mask[10:40, 25:40] = 255  # 1 px gap at column 24
    cleaned = clean_mask(mask)
    assert cleaned[5, 5] == 0
    assert cleaned[20:30, 24].all()


def test_frame_size_change_is_refused():
    subtractor = BackgroundSubtractor()
    subtractor.subtract(np.zeros((48, 64, 3), np.uint8))
    with pytest.raises(ExtractionError, match="frame size changed from 64x48 to 32x48"):
        subtractor.subtract(np.zeros((48, 32, 3), np.uint8))


@pytest.mark.parametrize("options", [{"working_width": 8}, {"history": 0},
                                     {"warmup_frames": -1}, {"var_min": 0.0}])
def test_bad_settings_are_refused(options):
    with pytest.raises(ExtractionError):
        BackgroundSubtractor(**options)


def test_gray_frame_array_is_refused():
    with pytest.raises(ExtractionError, match=r"BGR uint8 \(H, W, 3\)"):
        BackgroundSubtractor().subtract(np.zeros((48, 64), np.uint8))


def test_person_cut_at_the_waist_is_joined_into_one():
    mask = np.zeros((120, 160), np.uint8)
    mask[10:50, 70:90] = 255          # upper body
    mask[54:110, 72:88] = 255         # legs, 4 px below: subtraction lost the waist
    mask[20:100, 10:25] = 255         # another person, side by side: stays separate
    people = person_masks(mask, (160, 120), min_area_fraction=0.01)
    assert len(people) == 2
    joined = max(people, key=lambda p: p.bbox[3] * p.bbox[2] if p.bbox[0] > 50 else 0)
    assert joined.bbox == (70, 10, 20, 100)
    # The gap is bridged: one outline, every row of the person has foreground.
    assert joined.mask.any(axis=1).all()
    contours, _ = cv2.findContours(joined.mask.astype(np.uint8), cv2.RETR_EXTERNAL,
                                   cv2.CHAIN_APPROX_SIMPLE)
    assert len(contours) == 1
    separate = person_masks(mask, (160, 120), min_area_fraction=0.01, merge_fragments=False)
    assert len(separate) == 3


def test_fragment_below_and_beside_a_person_joins_it():
    mask = np.zeros((120, 160), np.uint8)
    mask[10:90, 70:90] = 255          # a person, legs lost below the knee on one side
    mask[95:105, 58:68] = 255         # a foot below and to the left: no x-overlap
    mask[40:48, 94:102] = 255         # a hand beside the hip, 4 px off
    mask[20:100, 10:25] = 255         # another person, side by side: stays separate
    people = person_masks(mask, (160, 120), min_area_fraction=0.002)
    assert len(people) == 2
    person = max(people, key=lambda p: p.bbox[0])
    assert person.bbox == (58, 10, 44, 95)
    assert person.area == 80 * 20 + 100 + 64
    # The old rule (pieces stacked above one another only) leaves the foot and the hand apart.
    assert len(person_masks(mask, (160, 120), min_area_fraction=0.002,
                            max_fragment_area=0.0)) == 4


def test_fragment_far_from_a_person_or_as_big_stays_apart():
    mask = np.zeros((120, 200), np.uint8)
    mask[10:90, 70:90] = 255          # a person 80 px tall
    mask[100:110, 20:30] = 255        # a blob 40 px left of the feet: beyond a quarter height
    mask[10:90, 95:115] = 255         # a second person 5 px beside: as big, not a fragment
    people = person_masks(mask, (200, 120), min_area_fraction=0.002)
    assert len(people) == 3


def test_cleaning_keeps_the_outline_and_drops_isolated_specks():
    mask = np.zeros((60, 60), np.uint8)
    mask[10:50, 20:35] = 255          # a leg: the opening shaves its corners
    mask[48:50, 35:37] = 255          # the tip of a toe, 2 px thick: the opening removes it
    mask[5:7, 50:52] = 255            # a speck of that size on its own
    cleaned = clean_mask(mask, close_px=1)
    assert np.array_equal(cleaned[:, :45], mask[:, :45]) and not cleaned[5:7, 50:52].any()
    plain = clean_mask(mask, close_px=1, restore_px=0)
    assert not plain[10, 20] and not plain[48:50, 36].any() and not plain[5:7, 50:52].any()


def arm_scene(bg: np.ndarray, arm_left: bool) -> tuple[np.ndarray, np.ndarray]:
    """A still red torso over the textured ``bg`` with one arm out to the left or the right,
    legs below: (frame BGR uint8 (240, 320, 3), the arm's truth bool (240, 320))."""
    frame, arm = bg.copy(), np.zeros(bg.shape[:2], np.uint8)
    cv2.rectangle(frame, (140, 60), (180, 150), (30, 30, 200), -1)           # torso
    cv2.rectangle(frame, (145, 150), (175, 220), (30, 30, 200), -1)          # legs
    x0, x1 = (90, 140) if arm_left else (180, 230)
    cv2.rectangle(arm, (x0, 70), (x1, 82), 255, -1)
    frame[arm > 0] = (30, 30, 200)
    return frame, arm > 0


def test_kept_colour_models_still_follow_an_arm_that_moved():
    bg = background(320, 240, seed=5)
    zone = np.zeros((240, 320), bool)
    zone[50:160, 80:240] = True                   # where the median showed the person
    legs = np.zeros((240, 320), np.uint8)
    legs[160:221, 145:176] = 255                  # moving, so the subtractor sees them
    refiner = ZoneRefiner(relearn_every=5)
    shadow = np.zeros_like(zone)
    for arm_left in (True, False):
        frame, arm = arm_scene(bg, arm_left)
        person = refiner(legs, frame, shadow, zone) > 0
        other_side = arm_scene(bg, not arm_left)[1]
        assert person[arm].mean() > 0.9 and person[other_side].mean() < 0.1, arm_left
        assert person[70:140, 145:175].all()      # the still torso, filled in by colour
    assert (refiner.learned, refiner.kept) == (1, 1)


def test_zone_refiner_learning_every_frame_is_refine_in_zone():
    bg = background(320, 240, seed=6)
    zone = np.zeros((240, 320), bool)
    zone[50:160, 80:240] = True
    legs = np.zeros((240, 320), np.uint8)
    legs[160:221, 145:176] = 255
    shadow = np.zeros_like(zone)
    refiner = ZoneRefiner(relearn_every=1)
    for arm_left in (True, False, True):
        frame = arm_scene(bg, arm_left)[0]
        assert np.array_equal(refiner(legs, frame, shadow, zone),
                              refine_in_zone(legs, frame, shadow, zone))
    assert refiner.kept == 0


@pytest.mark.parametrize("options", [{"relearn_every": 0}, {"min_iou": 1.5}])
def test_bad_zone_refiner_settings_are_refused(options):
    with pytest.raises(ExtractionError):
        ZoneRefiner(**options)


def test_box_without_background_keeps_its_seeds_and_learns_again_next_frame():
    frame = background(120, 100, seed=7)
    zone = np.ones((100, 120), bool)
    zone[:, :30] = False                          # the only pixels outside the zone are person
    mask = np.zeros((100, 120), np.uint8)
    mask[:, :30] = 255
    refiner = ZoneRefiner()
    for _ in range(2):
        out = refiner(mask, frame, np.zeros_like(zone), zone)
        assert (out > 0).all()                    # grabCut cannot run: foreground and zone kept
    assert (refiner.learned, refiner.kept) == (2, 0)


def ghost_scene(bg: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """arm_scene's person (arm to the right) and, left of the torso inside the zone, a ghost:
    foreground where the frame shows only the background (the median held the arm there).
    Returns (frame, foreground uint8 255 = found, zone bool, ghost bool), all (240, 320)."""
    frame, arm = arm_scene(bg, arm_left=False)
    zone = np.zeros((240, 320), bool)
    zone[50:160, 80:240] = True
    ghost = np.zeros((240, 320), bool)
    ghost[66:86, 90:140] = True
    found = np.zeros((240, 320), np.uint8)
    found[160:221, 145:176] = 255                 # the legs, moving, outside the zone
    found[arm] = 255                              # the arm that moved into view
    found[ghost] = 255
    return frame, found, zone, ghost


@pytest.mark.parametrize("trust", [True, False])
def test_colour_decides_on_a_ghost_only_when_the_zone_foreground_is_not_trusted(trust):
    bg = background(320, 240, seed=8)
    frame, found, zone, ghost = ghost_scene(bg)
    shadow = np.zeros_like(zone)
    person = refine_in_zone(found, frame, shadow, zone, trust_zone_foreground=trust) > 0
    refiner = ZoneRefiner(relearn_every=1, trust_zone_foreground=trust)
    assert np.array_equal(person, refiner(found, frame, shadow, zone) > 0)
    assert person[70:140, 145:175].all() and person[160:221, 145:176].all()   # torso, legs
    if trust:
        assert person[ghost].all()                # sure person: the ghost stays
    else:
        assert person[ghost].mean() < 0.1         # the background's colours: dropped


def test_a_colour_cut_that_loses_the_person_is_cut_again_with_the_foreground_sure():
    """A person the colours cannot tell from the background inside the zone (here: not drawn
    at all, only found by the subtractor) would be cut away whole; the box is cut again with
    the foreground sure instead (tracker.video.zone.COLLAPSED_SHARE)."""
    frame = background(320, 240, seed=9)
    found = np.zeros((240, 320), np.uint8)
    found[60:200, 140:180] = 255                  # a person-sized blob...
    zone = np.zeros((240, 320), bool)
    zone[50:190, 120:200] = True                  # ...mostly in the zone, its feet outside
    shadow = np.zeros_like(zone)
    for cut in (refine_in_zone(found, frame, shadow, zone, trust_zone_foreground=False),
                ZoneRefiner(trust_zone_foreground=False)(found, frame, shadow, zone)):
        assert (cut[found > 0] > 0).mean() > 0.95
    # A cut that keeps at least the share is left as it is.
    box = (slice(40, 220), slice(100, 220))
    half = found[box].copy()
    half[:, :60] = 0                              # keeps 20 of the 40 columns: a half
    assert _unless_collapsed(half, frame[box], found[box] > 0, shadow[box], zone[box],
                             400) is half


def test_zone_labels_keep_foreground_outside_the_zone_sure():
    found = np.zeros((4, 4), bool)
    found[:, :2] = True
    zone = np.zeros((4, 4), bool)
    zone[:2] = True
    shadow = np.zeros((4, 4), bool)
    trusted = _zone_labels(found, shadow, zone)
    assert (trusted[found] == cv2.GC_FGD).all()
    colour = _zone_labels(found, shadow, zone, trust_zone_foreground=False)
    assert (colour[found & ~zone] == cv2.GC_FGD).all()
    assert (colour[zone] == cv2.GC_PR_FGD).all() and (colour[~found & ~zone] == cv2.GC_BGD).all()



def test_a_black_or_blank_frame_shows_nobody_and_leaves_the_model_as_it_was():
    """A black frame had divided by a zero gain and made the whole image one "person"."""
    import warnings
    rng = np.random.default_rng(9)
    bg = background(320, 240)
    extractor = SilhouetteExtractor()
    extractor.prime(bg)
    frame, truth = scene(bg, [(160, 130)], 150, rng)
    with warnings.catch_warnings():
        warnings.simplefilter("error")                 # no "divide by zero" either
        for blank in (np.zeros_like(bg), np.full_like(bg, 255)):
            assert extractor(blank) == []
    people = extractor(frame)                          # the model did not learn the blanks
    assert len(people) == 1 and iou(people[0], truth) > 0.9


def test_a_component_over_half_the_image_is_no_person():
    mask = np.zeros((120, 160), np.uint8)
    mask[5:115, 5:155] = 255                           # 86 % of the image
    assert person_masks(mask, (160, 120)) == []
    assert len(person_masks(mask, (160, 120), max_area_fraction=0.9)) == 1
    mask[:] = 0
    mask[20:110, 60:100] = 255                         # 19 %: a person close to the camera
    assert len(person_masks(mask, (160, 120))) == 1


@pytest.mark.parametrize("trust", [True, False])
def test_the_zone_refiner_is_made_on_first_use_with_the_extractors_settings(trust):
    """The extractor makes its ZoneRefiner (tracker.video.zone) only for a frame with an
    unreliable zone, with its refine_relearn_every and trust_zone_foreground; priming again
    drops it (a new scene)."""
    from tracker.video.background import ClipBackground
    bg = background(160, 120, seed=3)
    extractor = SilhouetteExtractor(refine_relearn_every=4, trust_zone_foreground=trust,
                                    warmup_frames=0, adapt_noise_floor=False)
    extractor.prime(bg)
    extractor(bg)
    assert extractor.refiner is None                      # a clean plate: no zone
    zone = np.zeros(bg.shape[:2], bool)
    zone[30:90, 60:100] = True
    extractor.background = ClipBackground(extractor.subtractor.reference, zone)
    extractor(bg)
    refiner = extractor.refiner
    assert isinstance(refiner, ZoneRefiner)
    assert (refiner.relearn_every, refiner.trust_zone_foreground) == (4, trust)
    extractor.prime(bg)
    assert extractor.refiner is None


def test_bad_refine_relearn_every_is_refused():
    with pytest.raises(ExtractionError, match="refine_relearn_every"):
        SilhouetteExtractor(refine_relearn_every=0)
