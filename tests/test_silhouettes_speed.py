"""The silhouette extractor's faster routines give what the plain whole-image ones give."""
from __future__ import annotations

import cv2
import numpy as np

from tracker.video.silhouettes import (SilhouetteExtractor, clean_mask, drop_lighting_blobs,
                                 enclosed_shadow, person_masks)

from test_silhouettes import background, draw_person


def _frame(bg: np.ndarray, i: int, rng: np.random.Generator) -> np.ndarray:
    """A walker crossing the image to its left edge, with dark shorts (a darker shade of the
    background there: MOG2's shadow, enclosed by the body), a patch of the background lit
    brighter, and specks."""
    frame = bg.copy()
    x = 300 - 24 * i
    draw_person(frame, (x, 300), 260)
    shorts = (slice(300, 330), slice(max(x - 30, 0), max(x + 30, 0)))
    frame[shorts] = (bg[shorts] * 0.6).astype(np.uint8)
    patch = (slice(40, 90), slice(400, 470))
    frame[patch] = np.clip(bg[patch] * 1.35, 0, 255).astype(np.uint8)
    specks = rng.random(bg.shape[:2]) < 0.002
    frame[specks] = 255 - frame[specks]
    return cv2.add(frame, rng.integers(0, 6, bg.shape, dtype=np.uint8))


def _whole_image_people(extractor: SilhouetteExtractor, frame: np.ndarray):
    """SilhouetteExtractor's steps on the whole working-size image, one after the other."""
    small, raw = extractor.subtractor.subtract(frame)
    mask = (raw > 200).astype(np.uint8) * 255
    solid = clean_mask(mask, extractor.open_px, 1, extractor.restore_px) > 0
    mask |= enclosed_shadow(solid, raw == 127)
    cleaned = clean_mask(mask, extractor.open_px, extractor.close_px, extractor.restore_px)
    cleaned = drop_lighting_blobs(cleaned, small, extractor.background.image,
                                  min_area=int(extractor.min_area_fraction * cleaned.size))
    return person_masks(cleaned, (frame.shape[1], frame.shape[0]),
                        extractor.min_area_fraction, extractor.max_hole_fraction,
                        max_fragment_area=extractor.max_fragment_area, image=small)


def test_cleaning_in_the_foreground_box_gives_the_whole_images_people():
    """The extractor cleans only the box around the foreground: the same people, masks, boxes,
    centroids and colours as the whole image's cleaning, also where the person leaves the
    image and the box is cut by its edge."""
    bg = background(640, 480, seed=4)
    fast, plain = SilhouetteExtractor(), SilhouetteExtractor()
    for extractor in (fast, plain):
        extractor.prime(bg)
    rng = np.random.default_rng(5)
    found = 0
    for i in range(14):
        frame = _frame(bg, i, rng)
        got, want = fast(frame), _whole_image_people(plain, frame)
        assert len(got) == len(want)
        for a, b in zip(got, want):
            assert a.bbox == b.bbox and a.area == b.area and a.centroid == b.centroid
            np.testing.assert_array_equal(a.mask, b.mask)
            np.testing.assert_array_equal(a.colour, b.colour)
        found += len(got)
    assert found >= 12                        # the walker, until it has left the image


def _plain_drop(mask, frame, background, min_correlation=0.85, max_ratio_spread=0.08):
    """drop_lighting_blobs as its docstring says it, with numpy's median and mean."""
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    out = mask.copy()
    for contour in contours:
        x, y, w, h = cv2.boundingRect(contour)
        if w * h < 16:
            continue
        blob = np.zeros((h, w), np.uint8)
        cv2.drawContours(blob, [contour], -1, 255, cv2.FILLED, offset=(-x, -y))
        inside = blob > 0
        f = frame[y:y + h, x:x + w][inside].astype(np.float32) + 4.0
        b = background[y:y + h, x:x + w][inside].astype(np.float32) + 4.0
        log_ratio = np.log(f / b)
        spread = float(np.median(np.abs(log_ratio - np.median(log_ratio))))
        fg, bg = f.mean(axis=1) - f.mean(), b.mean(axis=1) - b.mean()
        denominator = float(np.sqrt((fg * fg).sum() * (bg * bg).sum()))
        correlation = float((fg * bg).sum()) / denominator if denominator > 0 else 0.0
        if correlation > min_correlation or spread < max_ratio_spread:
            out[y:y + h, x:x + w][inside] = 0
    return out


def test_relit_blobs_are_dropped_as_the_plain_rule_drops_them():
    """Patches of the background lit brighter or darker (odd and even pixel counts) go, the
    person stays; blob by blob the decisions are the plain rule's."""
    rng = np.random.default_rng(6)
    bg = background(320, 240, seed=7)
    for trial in range(20):
        frame, mask = bg.copy(), np.zeros((240, 320), np.uint8)
        draw_person(frame, (160, 130), 150)
        draw_person(mask, (160, 130), 150, colour=255)
        for _ in range(3):
            x, y = rng.integers(0, 280), rng.integers(0, 200)
            w, h = rng.integers(5, 40), rng.integers(5, 40)
            frame[y:y + h, x:x + w] = np.clip(bg[y:y + h, x:x + w] * rng.uniform(0.5, 1.6)
                                              + rng.normal(0, trial, (h, w, 3)), 0, 255)
            mask[y:y + h, x:x + w] = 255
        out = drop_lighting_blobs(mask, frame, bg)
        np.testing.assert_array_equal(out, _plain_drop(mask, frame, bg))
        assert out[130, 160] == 255
        if trial == 0:               # noiseless relit patches: all gone, the person alone left
            assert len(cv2.findContours(out, cv2.RETR_EXTERNAL,
                                        cv2.CHAIN_APPROX_SIMPLE)[0]) == 1


def test_people_touching_the_image_edge_are_traced_as_away_from_it():
    """person_masks traces contours in the box around the foreground: people cut by the
    image's edges (with holes kept and filled) come out as the same people placed further
    inside a larger image."""
    rng = np.random.default_rng(8)
    for _ in range(10):
        mask = np.zeros((120, 160), np.uint8)
        for _ in range(3):
            centre = (int(rng.integers(0, 160)), int(rng.integers(0, 120)))
            axes = (int(rng.integers(8, 40)), int(rng.integers(15, 60)))
            cv2.ellipse(mask, centre, axes, 0, 0, 360, 255, -1)
            cv2.circle(mask, centre, int(rng.integers(1, 6)), 0, -1)        # a hole, or none
        big = cv2.copyMakeBorder(mask, 7, 9, 5, 11, cv2.BORDER_CONSTANT, value=0)
        ratio = mask.size / big.size
        near = person_masks(mask, (160, 120), 0.0, 0.002, max_area_fraction=1.0)
        far = person_masks(big, (176, 136), 0.0, 0.002 * ratio, max_area_fraction=1.0)
        assert len(near) == len(far) >= 1
        for a, b in zip(near, far):
            assert a.bbox == (b.bbox[0] - 5, b.bbox[1] - 7, b.bbox[2], b.bbox[3])
            assert a.area == b.area
            np.testing.assert_allclose(a.centroid, (b.centroid[0] - 5, b.centroid[1] - 7))
            np.testing.assert_array_equal(a.mask, b.mask)


def test_a_frame_without_foreground_still_clears_the_kept_colour_models():
    """With an unreliable zone, a frame where nobody is found passes through the zone
    refiner as before the box-cropped cleaning: its kept colour models are dropped, so the
    next person is cut with models learned anew."""
    from tracker.video.background import ClipBackground
    bg = background(320, 240, seed=9)
    extractor = SilhouetteExtractor()
    extractor.prime(bg)
    zone = np.zeros((240, 320), bool)
    zone[60:200, 100:220] = True
    extractor.background = ClipBackground(extractor.background.image, zone)
    rng = np.random.default_rng(10)
    person = bg.copy()
    draw_person(person, (150, 130), 160)
    for frame in (person, bg, person):
        extractor(cv2.add(frame, rng.integers(0, 4, bg.shape, dtype=np.uint8)))
    assert (extractor.refiner.learned, extractor.refiner.kept) == (2, 0)


def test_the_padded_box_is_the_box_of_the_nonzero_pixels():
    """_padded_box takes boundingRect of the mask itself: the box findNonZero's points give,
    also for a view into a larger mask, and None for an empty one."""
    from tracker.video.silhouettes import _padded_box
    rng = np.random.default_rng(7)
    for _ in range(300):
        h, w = rng.integers(1, 50, 2)
        big = ((rng.random((h + 9, w + 9)) < rng.choice([0.001, 0.02, 0.4])) * 255)
        mask = big.astype(np.uint8)[4:4 + h, 2:2 + w]
        margin = int(rng.integers(0, 4))
        points = cv2.findNonZero(mask)
        if points is None:
            assert _padded_box(mask, margin) is None
            continue
        x, y, bw, bh = cv2.boundingRect(points)
        assert _padded_box(mask, margin) == (slice(max(y - margin, 0), min(y + bh + margin, h)),
                                             slice(max(x - margin, 0), min(x + bw + margin, w)))
