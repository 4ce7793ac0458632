"""A track's belief over (facing - direction of travel): learned from motion capture, carried
over time by the front/back chain (tracker.hypotheses.FrontBackTracker.offset_memory)."""
from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from regressor.angles import pose_angles, wrap_deg
from sequences.bvh import write_bvh
from sequences.skeleton import CMU_JOINT_NAMES
from tests.synthetic import cmu_motion
from tracker.filtering import PoseKalmanFilter
from tracker.hypotheses import FrontBackTracker, _with_flips
from tracker.offline.hypothesis_priors import facing_minus_travel, facing_travel_steps
from tracker.travel import (FACING_TRAVEL_PRIOR, FACING_TRAVEL_STEPS, fuse_with_prior,
                            fuse_with_priors, offset_likelihoods, offset_transition,
                            travel_likelihood)

FPS = 30.0
BINS = len(FACING_TRAVEL_PRIOR)


@pytest.fixture(autouse=True, scope="module")
def one_blas_thread():
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def _heading(pose: np.ndarray) -> float:
    return float(np.degrees(np.arctan2(pose[1], pose[0])))


def test_the_transition_keeps_probability_and_scales_with_the_share_of_a_frame():
    one = offset_transition(1.0)
    np.testing.assert_allclose(one.sum(axis=1), 1.0)
    assert np.all(one >= 0)
    np.testing.assert_allclose(np.diag(one), 1.0 - FACING_TRAVEL_STEPS.sum(axis=0))
    assert one[6, 5] == pytest.approx(FACING_TRAVEL_STEPS[0, 6])        # 180 -> 150
    assert one[6, 7] == pytest.approx(FACING_TRAVEL_STEPS[1, 6])        # 180 -> 210
    assert one[0, 11] == pytest.approx(FACING_TRAVEL_STEPS[0, 0])       # wraps round
    np.testing.assert_allclose(offset_transition(0.0), np.eye(BINS))
    np.testing.assert_allclose(offset_transition(2.0), one @ one)
    quarter = offset_transition(0.25)
    np.testing.assert_allclose(np.eye(BINS) - quarter, 0.25 * (np.eye(BINS) - one))
    np.testing.assert_allclose(offset_transition(1.2).sum(axis=1), 1.0)
    with pytest.raises(ValueError, match="share"):
        offset_transition(-1.0)


def test_the_steps_are_learned_where_the_body_turns_against_its_travel(tmp_path):
    """Travel straight on while the body turns 3 degrees a frame: (facing - travel) climbs
    one 30-degree bin every 10 frames, always the same way; a body that does not turn never
    steps."""
    T = 480
    euler = np.zeros((T, len(CMU_JOINT_NAMES), 3))
    root = np.zeros((T, 3))
    root[:, 1] = 17.0
    root[:, 2] = np.arange(T) * 0.6                # ~1.2 body heights a second along z
    write_bvh(tmp_path / "straight.bvh", cmu_motion(euler, root))
    euler[:, 0, 1] = 3.0 * np.arange(T)             # the root's yaw turns
    write_bvh(tmp_path / "turning.bvh", cmu_motion(euler, root))

    steps, counts = facing_travel_steps([tmp_path / "straight.bvh"])
    assert counts.sum() > T - 20 and np.all(steps == 0)
    offsets = facing_minus_travel(tmp_path / "turning.bvh")
    assert np.all(np.abs(wrap_deg(np.diff(offsets)) - 3.0) < 0.5)
    steps, counts = facing_travel_steps([tmp_path / "turning.bvh"])
    visited = counts > 20
    assert visited.sum() == BINS
    np.testing.assert_allclose(steps[1, visited], 0.1, atol=0.02)      # one bin per 10 frames
    assert np.all(steps[0] == 0)


def test_the_bins_likelihoods_weighed_by_the_prior_are_the_travel_likelihood():
    headings = np.array([-170.0, -60.0, 0.0, 55.0, 135.0])
    like = offset_likelihoods(headings, 30.0)
    assert like.shape == (5, BINS) and np.all(like > 0)
    np.testing.assert_allclose(like @ FACING_TRAVEL_PRIOR, travel_likelihood(headings, 30.0))
    assert like[3].argmax() == 1 and like[0].argmax() == 5       # 25 -> bin 30, -200 -> 150


def _sideways_pose(heading: float, rng) -> np.ndarray:
    pose = np.concatenate([[0.0, 0.0], rng.uniform(-30, 30, 53)])
    pose[0], pose[1] = np.cos(np.radians(heading)), np.sin(np.radians(heading))
    return pose


def test_a_belief_that_the_body_moves_sideways_pulls_its_heading_less_towards_travel():
    pose = _sideways_pose(80.0, np.random.default_rng(0))
    population, _ = fuse_with_prior(pose, 0.0, raw_variance=37.0 ** 2)
    sideways = np.full(BINS, 0.01)
    sideways[3] = 1.0 - 0.01 * (BINS - 1)
    own, _ = fuse_with_prior(pose, 0.0, raw_variance=37.0 ** 2, prior=sideways)
    assert _heading(population) < 70.0                   # the population walks forwards
    assert abs(_heading(own) - 85.0) < 6.0               # pulled towards travel + 90


def _fused_heading(heading: float, travel: float, raw_variance: float, prior) -> float:
    """fuse_with_prior's heading written out for one pose (the reference for the batch)."""
    offsets = np.arange(BINS) * 30.0
    miss = wrap_deg(heading - travel - offsets)
    w = prior * np.exp(-0.5 * miss ** 2 / (raw_variance + 25.0 ** 2))
    w /= w.sum()
    mean = np.degrees(np.arctan2(w @ np.sin(np.radians(offsets)),
                                 w @ np.cos(np.radians(offsets))))
    spread = w @ wrap_deg(offsets - mean) ** 2
    gain = (1 / (25.0 ** 2 + spread)) / (1 / raw_variance + 1 / (25.0 ** 2 + spread))
    return float(wrap_deg(heading + gain * wrap_deg(travel + mean - heading)))


def test_fusing_many_poses_under_many_priors_is_fusing_each_pair():
    rng = np.random.default_rng(5)
    headings = (-150.0, 10.0, 95.0)
    poses = np.array([_sideways_pose(h, rng) for h in headings])
    priors = np.array([FACING_TRAVEL_PRIOR, np.roll(FACING_TRAVEL_PRIOR, 6)])
    for travel in (20.0, -100.0):
        fused, variances = fuse_with_priors(poses, travel, 900.0, priors)
        assert fused.shape == (2, 3, 55) and variances.shape == (2, 3)
        for i in range(2):
            for k in range(3):
                expected = _fused_heading(headings[k], travel, 900.0, priors[i])
                assert _heading(fused[i, k]) == pytest.approx(expected, abs=1e-9)
                one, variance = fuse_with_prior(poses[k], travel, 900.0, prior=priors[i])
                np.testing.assert_allclose(fused[i, k], one, atol=1e-9)
                assert variances[i, k] == pytest.approx(variance) and variance < 900.0
        np.testing.assert_array_equal(fused[..., 2:],
                                      np.broadcast_to(poses[:, 2:], (2, 3, 53)))
        np.testing.assert_allclose(np.hypot(fused[..., 0], fused[..., 1]),
                                   np.broadcast_to(np.hypot(poses[:, 0], poses[:, 1]), (2, 3)))


def _walk(truth_heading: float, travel: float, memory: bool, T: int = 240, seed: int = 1):
    """A regressor that sees the body's heading with 25-degree noise and never flips it, a
    person moving steadily in direction ``travel``: the chain's filtered headings (T,) and
    its last beliefs over (facing - travel)."""
    rng = np.random.default_rng(seed)
    R = np.diag([37.0 ** 2] + [9.0] * 53)      # the shipped model's heading std is ~37 deg
    bank = FrontBackTracker(lambda fps: PoseKalmanFilter(fps, R=R), FPS, offset_memory=memory)
    body = _sideways_pose(0.0, rng)
    out = []
    for _ in range(T):
        raw = body.copy()
        h = np.radians(truth_heading + rng.normal(0.0, 25.0))
        raw[0], raw[1] = 0.8 * np.cos(h), 0.8 * np.sin(h)
        out.append(pose_angles(bank.step(_with_flips(raw[None], np.ones(1)), travel).filtered)[0])
    return np.array(out), bank


@pytest.mark.slow
def test_a_sideways_mover_keeps_its_heading_once_the_track_has_learned_its_offset():
    """Moving to the image's right (travel 90) while facing the camera (heading 0): the
    population's prior reads the body as turned towards its travel on every frame; the
    track's own belief learns that it moves sideways and stops pulling."""
    for seed in (1, 2, 3):
        without, _ = _walk(0.0, 90.0, memory=False, seed=seed)
        with_memory, bank = _walk(0.0, 90.0, memory=True, seed=seed)
        late = slice(120, None)
        assert np.mean(wrap_deg(without[late])) > 5.0          # pulled towards travel
        rms_without = np.sqrt(np.mean(wrap_deg(without[late]) ** 2))
        rms_with = np.sqrt(np.mean(wrap_deg(with_memory[late]) ** 2))
        assert rms_with < 0.75 * rms_without
        best = bank.offset_beliefs[bank.log_alpha.argmax()]
        assert best.argmax() == 9                   # facing - travel = -90: bin 270
        assert best[8:11].sum() > 0.5


def test_a_backward_walker_is_read_as_walking_backwards_and_stays_so():
    """Facing the camera (0) while walking away from it (travel 180): the track's belief
    settles on 180 and the decided heading stays near 0."""
    headings, bank = _walk(0.0, 180.0, memory=True, T=300, seed=4)
    assert np.all(np.abs(wrap_deg(headings[-100:])) < 30.0)
    best = bank.offset_beliefs[bank.log_alpha.argmax()]
    assert best.argmax() == 6 and best[6] > 0.5


def test_the_belief_waits_while_the_body_does_not_move_and_steps_per_30_fps_frame(monkeypatch):
    """Frames without travel leave the belief as it is (its steps were learned on moving
    frames); at 60 fps a frame is half a step's frame, whatever rate the model was trained at."""
    import tracker.hypotheses as hypotheses
    shares = []

    def recorded(share):
        shares.append(share)
        return offset_transition(share)
    monkeypatch.setattr(hypotheses, "offset_transition", recorded)
    rng = np.random.default_rng(0)
    bank = FrontBackTracker(lambda fps: PoseKalmanFilter(fps), 60.0, reference_fps=60.0)
    body = _sideways_pose(0.0, rng)
    for travel in (90.0, 90.0, None, None, 90.0):
        before = None if bank.offset_beliefs is None else bank.offset_beliefs.copy()
        bank.step(_with_flips(body[None], np.ones(1)), travel)
        if travel is None:        # each state's belief is its predecessor's, as it was
            for row in bank.offset_beliefs:
                assert any(np.allclose(row, old, rtol=1e-12, atol=0) for old in before)
    assert shares == [0.5, 0.5]           # the second and the last frame: moving, not first
