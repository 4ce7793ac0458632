"""Silhouettes turned upright for a rolled camera (tracker.video.roll, track --roll)."""
from __future__ import annotations

import numpy as np

from tracker.video.roll import upright_mask


def _leaning_bar(lean_deg: float) -> np.ndarray:
    """A 100 x 12 px bar whose top leans lean_deg degrees clockwise from image up."""
    m = np.zeros((160, 160), bool)
    t = np.linspace(-50, 50, 400)
    a = np.radians(lean_deg)
    for dx in np.linspace(-6, 6, 25):          # test data only: a thick line, built once
        x = 80 + t * np.sin(a) + dx * np.cos(a)
        y = 80 - t * np.cos(a) + dx * np.sin(a)
        m[np.round(y).astype(int), np.round(x).astype(int)] = True
    return m


def _lean(mask: np.ndarray) -> float:
    """Clockwise lean (degrees) of a mask's principal axis from image up."""
    ys, xs = np.nonzero(mask)
    cov = np.cov(np.vstack([xs - xs.mean(), ys - ys.mean()]))
    vx, vy = np.linalg.eigh(cov)[1][:, -1]
    if vy > 0:
        vx, vy = -vx, -vy                      # point it up (image y grows downwards)
    return float(np.degrees(np.arctan2(vx, -vy)))


def test_a_body_leaning_with_the_camera_roll_is_turned_upright():
    bar = _leaning_bar(20.0)
    assert abs(_lean(bar) - 20.0) < 2.0
    upright = upright_mask(bar, 20.0)
    assert abs(_lean(upright)) < 2.0
    assert abs(upright.sum() - bar.sum()) < 0.05 * bar.sum()       # nothing cut off
    assert abs(_lean(upright_mask(bar, -20.0)) - 40.0) < 2.0         # the other way: worse


def test_no_roll_leaves_the_mask_alone():
    bar = _leaning_bar(5.0)
    assert upright_mask(bar, 0.0) is bar


def test_the_tracker_describes_the_upright_silhouette():
    from dataclasses import replace
    from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
    from tracker import PoseTracker, TrackerSettings
    from tracker.video.silhouettes import PersonMask
    model = load_pose_model(DEFAULT_MODEL_PATH)
    seen = []
    described = replace(model)
    described.describe = lambda mask: seen.append(mask) or model.describe(mask)
    described.describe_with_mirror = \
        lambda mask: seen.append(mask) or model.describe_with_mirror(mask)
    bar = _leaning_bar(15.0)
    ys, xs = np.nonzero(bar)
    person = PersonMask(mask=bar, bbox=(0, 0, bar.shape[1], bar.shape[0]),
                        centroid=(float(xs.mean()), float(ys.mean())), area=int(bar.sum()))
    tracker = PoseTracker(described, 30.0, TrackerSettings(roll_deg=15.0))
    tracker.prime(np.zeros((160, 160, 3), np.uint8))
    tracker.describe(person)
    assert len(seen) == 1 and abs(_lean(seen[0])) < 2.0
