"""Which body the limbs are, decided over a whole track (tracker.member_path)."""
from __future__ import annotations

import numpy as np
import pytest

from regressor.angles import wrap_deg
from sequences.pose_vector import front_back_flip, pose_vector_names
from tracker.hypotheses import pick_member
from tracker.member_path import members_over_time

NAMES = pose_vector_names()
LEFT_HIP, RIGHT_HIP = NAMES.index("LeftUpLeg_x"), NAMES.index("RightUpLeg_x")


def _walk_in_profile(T=120, heading=85.0):
    """A body walking across the view, nearly in profile: its thighs swing in antiphase (30
    degrees, a stride a second at 30 fps). The networks give, frame by frame, either the body
    or its flip (their canonical member), and the decided heading wavers by 15 degrees, so the
    body's heading (85) and the flip's (95) are told apart by the heading only by chance."""
    rng = np.random.default_rng(4)
    t = np.arange(T)
    truth = np.zeros((T, 55))
    truth[:, 0], truth[:, 1] = np.cos(np.radians(heading)), np.sin(np.radians(heading))
    truth[:, LEFT_HIP] = 30 * np.sin(2 * np.pi * t / 30)
    truth[:, RIGHT_HIP] = -truth[:, LEFT_HIP]
    limbs = truth + np.concatenate([np.zeros((T, 2)), rng.normal(0, 1, (T, 53))], axis=1)
    given_flip = rng.random(T) < 0.5
    limbs[given_flip] = front_back_flip(limbs[given_flip])
    decided = heading + rng.normal(0, 15, T)
    return truth, limbs, decided


def _legs_swapped(poses, truth):
    """Frames whose thighs are nearer the truth's swapped than the truth's (mid-stride)."""
    own = np.abs(wrap_deg(poses[:, [LEFT_HIP, RIGHT_HIP]] - truth[:, [LEFT_HIP, RIGHT_HIP]]))
    other = np.abs(wrap_deg(poses[:, [LEFT_HIP, RIGHT_HIP]] - truth[:, [RIGHT_HIP, LEFT_HIP]]))
    stride = np.abs(truth[:, LEFT_HIP]) > 10
    return (own.sum(1) > other.sum(1)) & stride


def test_in_profile_the_legs_continuity_picks_the_body_where_the_heading_cannot():
    truth, limbs, decided = _walk_in_profile()
    by_heading = pick_member(limbs, decided)
    over_time = members_over_time(limbs, decided)
    assert _legs_swapped(by_heading, truth).mean() > 0.15       # the heading alone errs
    # The chain of members follows one body: the legs never swap mid-stride, and it is the
    # body's own (the heading's evidence, 85 against 95 on average, settles which). Where the
    # legs pass each other the two bodies nearly coincide and either may be taken.
    assert not _legs_swapped(over_time, truth).any()
    stride = np.abs(truth[:, LEFT_HIP]) > 10
    np.testing.assert_allclose(over_time[stride, :2], truth[stride, :2], atol=1e-9)


def test_away_from_profile_the_heading_decides_as_before():
    """Facing 30 degrees off the camera, the flip faces 150: the heading is never in doubt,
    and the chain takes each frame's member on its side even where that jumps."""
    truth, limbs, decided = _walk_in_profile(heading=30.0)
    np.testing.assert_allclose(members_over_time(limbs, decided), pick_member(limbs, decided))


def test_members_over_time_refuses_mismatched_inputs():
    with pytest.raises(ValueError, match="limbs must be"):
        members_over_time(np.zeros((5, 55)), np.zeros(4))
    with pytest.raises(ValueError, match="limbs must be"):
        members_over_time(np.zeros((5, 53)), np.zeros(5))
    assert members_over_time(np.zeros((0, 55)), np.zeros(0)).shape == (0, 55)
