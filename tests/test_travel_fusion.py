"""The direction of travel as front/back evidence and its fusion into a hypothesis's heading,
with the population's (facing - travel) distribution (tracker.travel)."""
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
from tracker.offline.hypothesis_priors import facing_minus_travel
from tracker.travel import FACING_TRAVEL_PRIOR, fuse_with_prior, travel_likelihood

FPS = 30.0
BINS = len(FACING_TRAVEL_PRIOR)


@pytest.fixture(autouse=True, scope="module")
def one_blas_thread():
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def _heading(pose: np.ndarray) -> float:
    return float(np.degrees(np.arctan2(pose[1], pose[0])))


def test_facing_minus_travel_follows_a_body_that_turns_against_its_travel(tmp_path):
    """Travel straight on while the body turns 3 degrees a frame: (facing - travel) climbs
    3 degrees a frame on every moving frame."""
    T = 120
    euler = np.zeros((T, len(CMU_JOINT_NAMES), 3))
    root = np.zeros((T, 3))
    root[:, 1] = 17.0
    root[:, 2] = np.arange(T) * 0.6                # ~1.2 body heights a second along z
    euler[:, 0, 1] = 3.0 * np.arange(T)             # the root's yaw turns
    write_bvh(tmp_path / "turning.bvh", cmu_motion(euler, root))
    offsets = facing_minus_travel(tmp_path / "turning.bvh")
    assert len(offsets) > T - 20
    assert np.all(np.abs(wrap_deg(np.diff(offsets)) - 3.0) < 0.5)


def test_the_travel_likelihood_is_the_offset_bins_weighed_by_the_population_prior():
    """Each bin's von Mises (std 25 deg widened by the bin's width) weighed by
    FACING_TRAVEL_PRIOR: written out for a few headings."""
    headings = np.array([-170.0, -60.0, 0.0, 55.0, 135.0])
    std = np.radians(np.hypot(25.0, 30.0 / np.sqrt(12.0)))
    kappa = 1.0 / std ** 2
    centres = np.radians(np.arange(BINS) * 30.0)
    per_bin = np.exp(kappa * np.cos(np.radians(headings - 30.0)[:, None] - centres)) / np.i0(kappa)
    np.testing.assert_allclose(travel_likelihood(headings, 30.0), per_bin @ FACING_TRAVEL_PRIOR,
                               rtol=1e-9)


def _sideways_pose(heading: float, rng) -> np.ndarray:
    pose = np.concatenate([[0.0, 0.0], rng.uniform(-30, 30, 53)])
    pose[0], pose[1] = np.cos(np.radians(heading)), np.sin(np.radians(heading))
    return pose


def test_a_sideways_body_is_pulled_towards_its_travel_less_than_a_forwards_one():
    """The population mostly walks forwards: a body facing 80 degrees off its travel is
    pulled towards it (a sideways offset is possible but rare), one facing 20 degrees off
    more strongly, and one facing away (backwards) towards travel + 180."""
    pose = _sideways_pose(80.0, np.random.default_rng(0))
    fused, variance = fuse_with_prior(pose, 0.0, raw_variance=37.0 ** 2)
    assert 40.0 < _heading(fused) < 75.0 and variance < 37.0 ** 2
    near, _ = fuse_with_prior(_sideways_pose(20.0, np.random.default_rng(0)), 0.0, 37.0 ** 2)
    assert _heading(near) < 15.0
    away, _ = fuse_with_prior(_sideways_pose(170.0, np.random.default_rng(0)), 0.0, 37.0 ** 2)
    assert abs(wrap_deg(_heading(away) - 180.0)) < 12.0


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


def test_fusing_many_poses_is_fusing_each():
    rng = np.random.default_rng(5)
    headings = (-150.0, 10.0, 95.0)
    poses = np.array([_sideways_pose(h, rng) for h in headings])
    for travel in (20.0, -100.0):
        fused, variances = fuse_with_prior(poses, travel, 900.0)
        assert fused.shape == (3, 55) and variances.shape == (3,)
        for k in range(3):
            expected = _fused_heading(headings[k], travel, 900.0, FACING_TRAVEL_PRIOR)
            assert _heading(fused[k]) == pytest.approx(expected, abs=1e-9)
            one, variance = fuse_with_prior(poses[k], travel, 900.0)
            np.testing.assert_allclose(fused[k], one, atol=1e-9)
            assert variances[k] == pytest.approx(variance) and variance < 900.0
        np.testing.assert_array_equal(fused[:, 2:], poses[:, 2:])
        np.testing.assert_allclose(np.hypot(fused[:, 0], fused[:, 1]),
                                   np.hypot(poses[:, 0], poses[:, 1]))


def _walk(truth_heading: float, travel: float, T: int = 240, seed: int = 1):
    """A regressor that sees the body's heading with 25-degree noise and never flips it, a
    person moving steadily in direction ``travel``: the chain's filtered headings (T,) and
    the chain."""
    rng = np.random.default_rng(seed)
    R = np.diag([37.0 ** 2] + [9.0] * 53)      # the shipped model's heading std is ~37 deg
    bank = FrontBackTracker(lambda fps: PoseKalmanFilter(fps, R=R), FPS)
    body = _sideways_pose(0.0, rng)
    out = []
    for _ in range(T):
        raw = body.copy()
        h = np.radians(truth_heading + rng.normal(0.0, 25.0))
        raw[0], raw[1] = 0.8 * np.cos(h), 0.8 * np.sin(h)
        out.append(pose_angles(bank.step(_with_flips(raw[None], np.ones(1)), travel).filtered)[0])
    return np.array(out), bank


def test_a_backward_walker_is_read_as_walking_backwards_and_stays_so():
    """Facing the camera (0) while walking away from it (travel 180): the regressor's heading
    is fused with travel + 180 (the population's backwards offset), so the decided heading
    stays near 0."""
    headings, _ = _walk(0.0, 180.0, T=300, seed=4)
    assert np.all(np.abs(wrap_deg(headings[-100:])) < 30.0)


def test_the_travel_is_each_hypothesis_evidence_tempered_by_the_travel_weight():
    """A frame's evidence for hypothesis j gains travel_weight * log travel_likelihood of its
    heading (the same whichever state came before)."""
    body = _sideways_pose(30.0, np.random.default_rng(2))
    hyp = _with_flips(body[None], np.ones(1))
    banks = [FrontBackTracker(lambda fps: PoseKalmanFilter(fps), FPS) for _ in range(2)]
    for bank, travel in zip(banks, (None, 10.0)):
        for _ in range(3):
            bank.step(hyp, travel)
    headings = np.degrees(np.arctan2(hyp.poses[:, 1], hyp.poses[:, 0]))
    gained = banks[1].history[-1].evidence - banks[0].history[-1].evidence
    np.testing.assert_allclose(gained, banks[1].travel_weight
                               * np.log(travel_likelihood(headings, 10.0)), rtol=1e-9)
