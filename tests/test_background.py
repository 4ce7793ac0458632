"""The clip background without a clean plate: where it cannot be trusted (tracker.video.background)."""
from __future__ import annotations

import numpy as np

from tracker.video.background import clip_background


def frames_with(boxes_per_frame, shape=(120, 160)) -> np.ndarray:
    """Grey frames (N, h, w, 3) with each frame's boxes (y0, y1, x0, x1) painted dark."""
    frames = np.full((len(boxes_per_frame),) + shape + (3,), 160, np.uint8)
    for frame, boxes in zip(frames, boxes_per_frame):
        for y0, y1, x0, x1 in boxes:
            frame[y0:y1, x0:x1] = 40
    return frames


def test_still_part_between_moving_limbs_under_a_moving_torso_is_unreliable():
    # A torso leaning to and fro (rows 20-60) over a standing leg that barely sways (columns
    # 55-68), a leg that swings (columns 85-110) and, between them, shorts that never change
    # (rows 60-72, columns 68-85): never busy and, open to the floor below, no hole.
    poses = [[(20, 60, 40, 80), (60, 100, 55, 65), (60, 100, 85, 95), (60, 72, 55, 95)],
             [(20, 60, 75, 115), (60, 100, 58, 68), (60, 100, 100, 110), (60, 72, 58, 100)]]
    frames = frames_with(poses * 4)
    assert clip_background(frames, bridge_px=31).unreliable[62:70, 70:83].all()
    assert not clip_background(frames, bridge_px=1).unreliable[62:70, 70:83].any()


def test_gap_between_two_people_side_by_side_stays_reliable():
    # Two people sway side by side, 29 px apart: nothing busy above the gap between them.
    frames = frames_with([[(20, 100, 40 + s, 56 + s), (20, 100, 95 - s, 111 - s)]
                          for s in (0, 5, 0, 5, 0, 5)])
    estimate = clip_background(frames, bridge_px=31)
    assert estimate.unreliable[40:80, 40:45].all()                 # the people themselves
    assert not estimate.unreliable[:, 66:84].any()


def test_a_slow_change_of_light_makes_no_unreliable_zone():
    """Brightness rising 0.85x -> 1.15x over the clip had made a bright sky busy in most
    frames, and its zone was taken for a person (tracker.video.zone.refine_in_zone)."""
    rng = np.random.default_rng(0)
    scene = np.clip(rng.normal(120, 40, (120, 160, 3)), 0, 255)
    scene[:50] = 200                                     # a bright, flat sky
    frames = np.stack([np.clip(scene * g, 0, 255).astype(np.uint8)
                       for g in np.linspace(0.85, 1.15, 25)])
    assert clip_background(frames).unreliable.mean() < 0.01
    # A person swaying on the spot is still found under the same change of light.
    frames[::2, 60:110, 60:80] = 20
    frames[1::2, 60:110, 75:95] = 20
    zone = clip_background(frames).unreliable
    assert zone[70:100, 62:93].all() and zone[:55].mean() < 0.01


def _median_gain(background: np.ndarray, frame: np.ndarray, step: int = 8) -> np.ndarray:
    """GainMeter's definition, written out: the per-channel np.median of frame / background
    over every step-th pixel that is neither dark nor bright in the background nor clipped
    in the frame (ones with under 16 such pixels)."""
    b = background[::step, ::step].reshape(-1, 3).astype(np.float32)
    f = frame[::step, ::step].reshape(-1, 3).astype(np.float32)
    ok = (b > 16).all(axis=1) & (b < 240).all(axis=1) & (f < 250).all(axis=1)
    if ok.sum() < 16:
        return np.ones(3, np.float32)
    return np.median(f[ok] / b[ok], axis=0)


def test_gain_meter_is_the_median_ratio_bit_for_bit():
    from tracker.video.background import GainMeter
    rng = np.random.default_rng(3)
    background = rng.integers(0, 256, (240, 320, 3), np.uint8)
    meter = GainMeter(background)
    frames = [np.clip(background * gain + rng.normal(0, 3, background.shape), 0, 255)
              .astype(np.uint8) for gain in (0.5, 0.97, 1.0, 1.3, 2.5)]
    frames += [rng.integers(0, 256, background.shape, np.uint8) for _ in range(20)]
    frames += [np.full_like(background, 255), np.zeros_like(background)]
    counts = set()
    for frame in frames:
        expected, got = _median_gain(background, frame), meter(frame)
        assert got.dtype == expected.dtype == np.float32 and got.shape == (3,)
        assert np.array_equal(got, expected)
        counts.add(int(((background[::8, ::8] > 16).all(axis=2) & (background[::8, ::8] < 240)
                        .all(axis=2) & (frame[::8, ::8] < 250).all(axis=2)).sum()) % 2)
    assert counts == {0, 1}             # both an odd and an even number of pixels measured


def test_learn_zone_given_the_median_learns_what_it_learns_computing_it():
    """run._prime hands learn_zone the median it primed with; the zone and floor are those
    learn_zone finds from the frames alone (also when frame gains make it recompute)."""
    from tracker.video.silhouettes import SilhouetteExtractor, median_background
    rng = np.random.default_rng(5)
    poses = [[(20, 60, 40 + s, 80 + s)] for s in (0, 7, 14, 21, 28, 35, 3)]
    frames = frames_with(poses).astype(np.int16) + rng.integers(-4, 5, (7, 120, 160, 3))
    frames[2] = frames[2] * 1.2                        # one frame brighter: its gain undone
    frames = list(np.clip(frames, 0, 255).astype(np.uint8))
    median = median_background(frames)
    given, computed = SilhouetteExtractor(), SilhouetteExtractor()
    for extractor, passed in ((given, median), (computed, None)):
        extractor.prime(median)
        extractor.learn_zone(frames, passed)
    assert given.background.unreliable.any()
    assert np.array_equal(given.background.unreliable, computed.background.unreliable)
    assert given.subtractor.var_min == computed.subtractor.var_min
    assert np.array_equal(clip_background(np.stack(frames), median=median).unreliable,
                          clip_background(np.stack(frames)).unreliable)
