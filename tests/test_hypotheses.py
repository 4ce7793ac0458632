"""Front/back hypotheses over time (tracker.tracks.hypotheses)."""
from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from regressor.angles import pose_angles, wrap_deg
from regressor.estimator import PoseEstimates
from sequences.pose_vector import front_back_flip
from tracker.tracks.filtering import PoseKalmanFilter
from tracker.tracks.flip_hypotheses import with_flips as _with_flips
from tracker.tracks.hypotheses import FrontBackTracker, Hypotheses, transition_matrix
from tracker.tracks.proposals import propose_batch

FPS = 30.0


@pytest.fixture(autouse=True, scope="module")
def one_blas_thread():
    """One BLAS thread, as track uses: the filters' small products only lose by sharing."""
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def _pose(heading_deg: float, norm: float = 1.0, seed: int = 0) -> np.ndarray:
    """A pose with asymmetric limbs (so its flip differs beyond the heading)."""
    rng = np.random.default_rng(seed)
    v = np.concatenate([[0.0, 0.0], rng.uniform(-40, 40, 53)])
    h = np.radians(heading_deg)
    v[0], v[1] = norm * np.cos(h), norm * np.sin(h)
    return v


def _factory(fps):
    return PoseKalmanFilter(fps)


def _run(truth_headings, flipped, norms, seed=1):
    """Feed the tracker a regressor that outputs the truth (plus noise) or its flip."""
    rng = np.random.default_rng(seed)
    bank = FrontBackTracker(_factory, FPS)
    body = _pose(0.0, seed=7)
    out = []
    for t, h in enumerate(truth_headings):
        true = body.copy()
        true[0], true[1] = norms[t] * np.cos(np.radians(h)), norms[t] * np.sin(np.radians(h))
        raw = true + np.concatenate([[0, 0], rng.normal(0, 3, 53)])
        if flipped[t]:
            raw = front_back_flip(raw)
        out.append(bank.step(_with_flips(raw[None], np.ones(1))))
    return bank, out


def test_hypotheses_are_the_pose_and_its_flip_and_a_mixture_adds_its_experts():
    raw = _pose(10.0, norm=0.4)
    h = _with_flips(raw[None], np.ones(1))
    assert h.poses.shape == (2, 55) and np.array_equal(h.raw, raw)
    np.testing.assert_allclose(h.poses[1], front_back_flip(h.poses[0]))

    class Mixture:                      # PoseEstimator's members that propose_batch uses
        canonical_priors = None

        def hypotheses(self, stacked, m, mirrored=None, novelty=True):   # rows (N, k*D)
            n = len(stacked)
            poses = np.array([_pose(10.0, 0.9), _pose(-60.0, 0.5)])
            return PoseEstimates(np.repeat(poses[None], n, axis=0), np.tile([0.7, 0.3], (n, 1)))

    (h,) = propose_batch(Mixture(), np.zeros((1, 6)))
    assert h.poses.shape == (4, 55) and h.log_evidence[0] > h.log_evidence[2]
    A = transition_matrix(4)
    np.testing.assert_allclose(A.sum(axis=1), 1.0)
    bank = FrontBackTracker(_factory, FPS)
    for _ in range(3):
        decision = bank.step(h)
    assert 0 <= decision.state < 4 and len(bank.viterbi_path()) == 3


def test_a_person_walking_backwards_ends_up_facing_the_right_way():
    """Walking away from the camera while facing it (heading 0): the regressor is ambiguous
    and flips often at first, then mostly right; the chain must settle on the right side."""
    T = 150
    rng = np.random.default_rng(3)
    truth = np.zeros(T)
    flipped = np.where(np.arange(T) < 40, rng.random(T) < 0.5, rng.random(T) < 0.15)
    norms = np.where(np.arange(T) < 40, 0.2, 0.7)
    bank, out = _run(truth, flipped, norms)
    late = np.array([pose_angles(d.filtered)[0] for d in out[-30:]])
    assert np.all(np.abs(wrap_deg(late)) < 30.0)
    smoothed = pose_angles(bank.smoothed())[:, 0]
    assert np.mean(np.abs(wrap_deg(smoothed[40:])) < 30.0) > 0.9


def test_a_turn_on_the_spot_is_followed_through_the_regressor_flips():
    """Turning on the spot at 60 deg/s: regressor flips on 20% of frames."""
    T = 180
    rng = np.random.default_rng(4)
    truth = wrap_deg(np.arange(T) * 60.0 / FPS)
    flipped = rng.random(T) < 0.2
    bank, out = _run(truth, flipped, np.full(T, 0.8))
    err = np.abs(wrap_deg(np.array([pose_angles(d.filtered)[0] for d in out]) - truth))
    assert np.mean(err[10:] < 30.0) > 0.9
    path = bank.viterbi_path()
    assert np.mean(path.astype(bool) == flipped) > 0.9


def test_body_angles_follow_the_regressors_own_pose_when_the_chain_chooses_the_flip():
    """The chain decides the heading; with a limb filter the output's 53 body angles are the
    filtered raw pose's, not the chosen flip's mirrored limbs (tracker.tracks.hypotheses, "Limbs")."""
    rng = np.random.default_rng(5)
    body = _pose(30.0, norm=0.9, seed=8)
    frames = []
    for _ in range(60):
        raw = body + np.concatenate([[0, 0], rng.normal(0, 2, 53)])
        h = _with_flips(raw[None], np.ones(1))
        frames.append(Hypotheses(h.poses, np.array([-4.0, 0.0]), raw))   # evidence: the flip
    split = FrontBackTracker(_factory, FPS, limb_filter_factory=_factory)
    coupled = FrontBackTracker(_factory, FPS)
    late_split = [split.step(h) for h in frames][-10:]
    late_coupled = [coupled.step(h) for h in frames][-10:]
    flip = front_back_flip(body)
    for d_split, d_coupled in zip(late_split, late_coupled):
        assert d_split.state == d_coupled.state == 1                     # the flip was chosen
        np.testing.assert_allclose(d_split.filtered[:2], d_coupled.filtered[:2])
        assert np.abs(wrap_deg(d_split.filtered[2:] - body[2:])).mean() < 2.0
        assert np.abs(wrap_deg(d_coupled.filtered[2:] - flip[2:])).mean() < 2.0
    smoothed = split.smoothed()
    assert np.abs(wrap_deg(smoothed[-10:, 2:] - body[2:])).mean() < 2.0
    np.testing.assert_allclose(smoothed[:, :2], coupled.smoothed()[:, :2])


def test_the_trackers_limb_filter_trusts_the_regressor_more_than_the_chains_filters():
    from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
    from tracker.pipeline import LIMB_R_SCALE, TrackerSettings
    from tracker.tracks.proposals import front_back_tracker
    model = load_pose_model(DEFAULT_MODEL_PATH)
    bank = front_back_tracker(model, FPS, TrackerSettings(r_scale=2.0))
    chain, limbs = bank.filter_factory(FPS), bank.limb_filter_factory(FPS)
    np.testing.assert_allclose(limbs.R, chain.R * LIMB_R_SCALE)
    np.testing.assert_allclose(chain.R, model.measurement_covariance * 2.0)
    custom = front_back_tracker(model, FPS, filter_factory=_factory)
    assert custom.limb_filter_factory is None and custom.filter_factory is _factory


def test_the_heading_filter_follows_a_short_confident_misreading_less():
    """HEADING_Q_SCALE scales the heading's process noise only. After a steady back view
    (150 deg), half a second of raw headings swings to a front view (10 deg) and back, as the
    regressor did on the shipped sample: the model's own q follows the swing almost all the
    way (about 165 deg off), the scaled one goes less than 0.75 of that."""
    from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
    from tracker.pipeline import HEADING_Q_SCALE, TrackerSettings, kalman_factory
    model = load_pose_model(DEFAULT_MODEL_PATH)
    stiff = kalman_factory(model)(FPS)
    loose = kalman_factory(model, TrackerSettings(heading_q_scale=1.0))(FPS)
    expected = model.process_noise.copy()
    expected[0] *= HEADING_Q_SCALE
    np.testing.assert_allclose(stiff.cv.q, expected)
    np.testing.assert_allclose(loose.cv.q, model.process_noise)
    swing = np.concatenate([np.full(60, 150.0), np.linspace(150, 10, 6)[1:], np.full(8, 10.0),
                            np.linspace(10, 150, 6)[1:], np.full(20, 150.0)])
    body = _pose(0.0, norm=0.8, seed=3)
    raws = []
    for h in swing:
        raw = body.copy()
        raw[0], raw[1] = 0.8 * np.cos(np.radians(h)), 0.8 * np.sin(np.radians(h))
        raws.append(raw)
    worst = {}
    for name, f in (("stiff", stiff), ("loose", loose)):
        out = np.array([pose_angles(f.step(r)[0])[0] for r in raws])
        worst[name] = np.abs(wrap_deg(out[60:] - 150.0)).max()
    assert worst["loose"] > 150.0 and worst["stiff"] < 0.75 * worst["loose"]


def test_pick_member_takes_the_member_nearer_the_heading():
    from tracker.tracks.hypotheses import pick_member
    pose = _pose(60.0, seed=2)
    flip = front_back_flip(pose)                       # heading 120, limbs exchanged
    np.testing.assert_allclose(pick_member(pose, 50.0), pose)
    np.testing.assert_allclose(pick_member(pose, 130.0), flip)
    both = pick_member(np.array([pose, pose]), np.array([170.0, -10.0]))
    np.testing.assert_allclose(both, [flip, pose])


def test_body_angles_follow_the_limb_heads_member_that_agrees_with_the_decided_heading():
    """The body faces 150 deg. The regressor's own pose reads the flip's heading (30 deg) and
    averages the two bodies (its limbs are zero); the limb head gives the canonical member
    (the flip, facing the camera's half). The evidence is for the flip of the own pose, so the
    chain decides 150: the output's body angles must be the body's, i.e. the member's flip
    (picking by the own pose's heading would give the member's mirrored limbs)."""
    rng = np.random.default_rng(6)
    body = _pose(150.0, norm=0.9, seed=9)
    member = front_back_flip(body)                                    # heading 30
    averaged = np.concatenate([member[:2], np.zeros(53)])
    with_head = FrontBackTracker(_factory, FPS, limb_filter_factory=_factory)
    without = FrontBackTracker(_factory, FPS, limb_filter_factory=_factory)
    for _ in range(60):
        noise = np.concatenate([[0, 0], rng.normal(0, 1, 53)])
        h = _with_flips((averaged + noise)[None], np.ones(1), member + noise)
        h = Hypotheses(h.poses, np.array([-4.0, 0.0]), h.raw, h.limbs)
        a, b = with_head.step(h), without.step(Hypotheses(h.poses, h.log_evidence, h.raw))
    assert abs(wrap_deg(pose_angles(a.filtered)[0] - 150.0)) < 5.0
    assert np.abs(wrap_deg(a.filtered[2:] - body[2:])).mean() < 2.0
    assert np.abs(wrap_deg(a.filtered[2:] - member[2:])).mean() > 10.0
    assert np.abs(b.filtered[2:]).mean() < 2.0 < np.abs(body[2:]).mean()
    smoothed = with_head.smoothed()
    assert abs(wrap_deg(pose_angles(smoothed[-1])[0] - 150.0)) < 5.0
    assert np.abs(wrap_deg(smoothed[-10:, 2:] - body[2:])).mean() < 2.0


def test_evidence_weight_tempers_the_regressors_evidence():
    """Exponent 0: the regressor's norm evidence is ignored and raw and flip start even."""
    h = _with_flips(_pose(10.0, norm=0.7)[None], np.ones(1))
    assert h.log_evidence[0] > h.log_evidence[1]          # evidence for the raw pose
    flat = FrontBackTracker(_factory, FPS, evidence_weight=0.0).step(h)
    assert flat.probability == pytest.approx(transition_matrix(2)[1, 0] /
                                             (transition_matrix(2)[1, 0] + transition_matrix(2)[0, 1]))
    full = FrontBackTracker(_factory, FPS, evidence_weight=1.0).step(h)
    assert full.probability > flat.probability


def test_weights_are_chosen_by_replaying_the_tracker_on_validation_renders(cmu_bvh_dir):
    from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
    from lab.hypothesis_priors import choose_weights, validation_renders
    model = load_pose_model(DEFAULT_MODEL_PATH)
    renders = validation_renders(model, [cmu_bvh_dir / "07_12.bvh"], frames=24)
    assert sorted(renders) == ["07_12 fixed", "07_12 fixed reversed", "07_12 spiral",
                               "07_12 spiral reversed"]
    forwards, backwards = (renders[f"07_12 fixed{s}"]["truth"] for s in ("", " reversed"))
    assert len(forwards) == len(backwards) == 24
    best, table = choose_weights(model, renders, evidence_weights=(0.5, 1.0))
    assert best in table and len(table) == 2
    assert all(0 <= rms <= 180 for rms in table[best].values())


def test_priors_are_learned_on_video_like_masks_unless_told_otherwise():
    """The front/back priors see masks as the model does in use (trained on video-like ones)."""
    from lab.hypothesis_priors import video_like
    masks = np.zeros((2, 224, 224), bool)
    masks[:, 30:190, 90:130] = True
    assert video_like(masks, on=False) is masks
    noisy = video_like(masks)
    assert len(noisy) == 2 and all(m.dtype == bool and 55 <= m.shape[0] <= 160 for m in noisy)
    assert not np.array_equal(noisy[0], masks[0, 30:190, 90:130])


def _steady_probability(fps: float, seconds: float, reference_fps: float) -> float:
    """The decided state's probability after feeding the same mildly ambiguous raw pose
    (heading norm 0.4: its evidence slightly favours it over its flip) for ``seconds``."""
    bank = FrontBackTracker(_factory, fps, reference_fps=reference_fps)
    h = _with_flips(_pose(10.0, norm=0.4)[None], np.ones(1))
    decision = None
    for _ in range(int(round(seconds * fps))):
        decision = bank.step(h)
    return decision.probability


def test_the_chain_weighs_evidence_per_second_not_per_frame():
    """The switch rates and evidence weights were learned on 30 fps sequences: a 60 or 120 fps
    video's frames are shares of such a frame, so the same evidence for the same time gives
    the same confidence; counted per frame, a 120 fps video would be four times as sure."""
    at_30 = _steady_probability(30.0, 0.5, reference_fps=30.0)
    for fps in (60.0, 120.0):
        tempered = _steady_probability(fps, 0.5, reference_fps=30.0)
        per_frame = _steady_probability(fps, 0.5, reference_fps=fps)
        assert tempered == pytest.approx(at_30, abs=0.05)     # measured: 0.75 / 0.74, 0.77
        assert per_frame > at_30 + 0.15                      # measured: 0.95 / 1.00
    bank = FrontBackTracker(_factory, 60.0, reference_fps=30.0)
    a, b = bank.frame_switch
    # switching in either of two 60 fps frames is as likely as in one 30 fps frame
    assert 1 - (1 - a) ** 2 == pytest.approx(bank.switch[0])
    assert 1 - (1 - b) ** 2 == pytest.approx(bank.switch[1])
    assert FrontBackTracker(_factory, 30.0).frame_switch == tuple(bank.switch)


def test_a_turn_on_the_spot_at_60_fps_is_followed_through_the_regressor_flips():
    """The turn of test_a_turn_on_the_spot_... filmed at 60 fps (flips on 20% of frames):
    tempering the evidence per second must not leave the chain unable to follow."""
    fps, T = 60.0, 360
    rng = np.random.default_rng(4)
    truth = wrap_deg(np.arange(T) * 60.0 / fps)
    flipped = rng.random(T) < 0.2
    bank = FrontBackTracker(_factory, fps, reference_fps=30.0)
    body = _pose(0.0, seed=7)
    out = []
    for t, h in enumerate(truth):
        raw = body.copy()
        raw[0], raw[1] = 0.8 * np.cos(np.radians(h)), 0.8 * np.sin(np.radians(h))
        raw = raw + np.concatenate([[0, 0], rng.normal(0, 3, 53)])
        out.append(bank.step(_with_flips((front_back_flip(raw) if flipped[t] else raw)[None],
                                         np.ones(1))))
    err = np.abs(wrap_deg(np.array([pose_angles(d.filtered)[0] for d in out]) - truth))
    assert np.mean(err[20:] < 30.0) > 0.9
