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
