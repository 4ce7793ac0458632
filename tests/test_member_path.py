"""Which body the limbs are, decided over a whole track (hypotheses.members_over_time)."""
from __future__ import annotations

import numpy as np
import pytest

from regressor.angles import wrap_deg
from sequences.pose_vector import front_back_flip, pose_vector_names
from tracker.tracks.hypotheses import members_over_time, pick_member

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


@pytest.mark.slow
def test_the_trackers_smoothed_output_takes_its_limbs_from_the_chain_of_members(monkeypatch):
    """FrontBackTracker.smoothed hands the whole track's limbs, the smoothed heading and the
    frame-rate ratio to members_over_time, and its body angles are the RTS smoothing of what
    that returns; the online (filtered) output still takes the member by the heading."""
    import tracker.tracks.hypotheses as hypotheses
    from sequences.pose_vector import heading_deg
    from tracker.tracks.filtering import PoseKalmanFilter
    from tracker.tracks.flip_hypotheses import with_flips as _with_flips
    from tracker.tracks.hypotheses import FrontBackTracker

    truth, limbs, _ = _walk_in_profile(T=60)
    calls = []

    def spy(members, headings, frame_rate_ratio=1.0):
        calls.append((np.array(members), np.array(headings), frame_rate_ratio))
        return truth                                 # what a perfect chain would return
    monkeypatch.setattr(hypotheses, "members_over_time", spy)
    bank = FrontBackTracker(PoseKalmanFilter, 60.0, limb_filter_factory=PoseKalmanFilter)
    for i in range(len(limbs)):
        raw = np.zeros(55)
        raw[:2] = truth[i, :2]
        bank.step(_with_flips(raw[None], np.ones(1), limbs[i]))
    assert not calls                                  # online: pick_member, as before
    smoothed = bank.smoothed()
    (members, headings, ratio), = calls
    np.testing.assert_allclose(members, limbs)
    np.testing.assert_allclose(headings, heading_deg(smoothed))
    assert ratio == pytest.approx(0.5)                # 60 fps against the 30 chosen at
    # Its legs are those returned (smoothed), not the random members'.
    assert not _legs_swapped(smoothed, truth).any()


def test_the_heading_evidence_is_tempered_by_the_frame_rate():
    """A body at 80 degrees with its legs apart (its flip at 100, legs swapped). The first 12
    frames' heading (60) says the body, the last 12's (120) the flip, each by 0.67 a frame.
    Changing body costs the legs' jump (3200 deg^2 / 800 = 4); each half's evidence is 8 at
    the rate the settings were chosen at, and a quarter of that at 120 fps, where the chain no
    longer pays for the change."""
    T = 24
    body = np.zeros((T, 55))
    body[:, 0], body[:, 1] = np.cos(np.radians(80.0)), np.sin(np.radians(80.0))
    body[:, LEFT_HIP], body[:, RIGHT_HIP] = 20.0, -20.0
    flip = front_back_flip(body)                                 # heading 100, legs swapped
    headings = np.where(np.arange(T) < 12, 60.0, 120.0)
    full = members_over_time(body, headings, step_variance=400.0)
    np.testing.assert_allclose(full, np.concatenate([body[:12], flip[12:]]))
    quarter = members_over_time(body, headings, frame_rate_ratio=0.25, step_variance=400.0)
    assert np.allclose(quarter, body) or np.allclose(quarter, flip)
