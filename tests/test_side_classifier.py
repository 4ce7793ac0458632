"""The front/back side classifier (regressor.side_classifier) and the chain's canonical
hypotheses (tracker.tracks.hypotheses.canonical_hypotheses)."""
from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from regressor.angles import pose_angles, wrap_deg
from regressor.model_writer import side_classifier_arrays
from regressor.side_classifier import SideClassifier
from sequences.pose_vector import front_back_flip
from tracker.tracks.filtering import PoseKalmanFilter
from tracker.tracks.hypotheses import (CANONICAL_EVIDENCE_WEIGHT, CANONICAL_SWITCH_PROBABILITY,
                                EVIDENCE_WEIGHT, SWITCH_PROBABILITY, FrontBackTracker,
                                canonical_hypotheses, chain_options)
from tracker.tracks.proposals import front_back_tracker

FPS = 30.0


def _classifier(P: int = 6) -> SideClassifier:
    """A hand-made classifier: front when the first input is positive (one hidden layer)."""
    W0 = np.zeros((P, 2))
    W0[0] = [4.0, -4.0]                       # relu(4 x), relu(-4 x)
    return SideClassifier([(W0, np.zeros(2)), (np.array([[1.0], [-1.0]]), np.zeros(1))],
                          np.zeros(P), 1.0)


def test_the_probability_follows_the_logit_and_survives_the_file_round_trip():
    clf = _classifier()
    X = np.zeros((3, 6))
    X[:, 0] = [-2.0, 0.0, 2.0]
    p = clf.front_probability(X)
    assert p[0] < 0.01 and p[1] == pytest.approx(0.5) and p[2] > 0.99
    back = SideClassifier.from_arrays(side_classifier_arrays(clf))
    np.testing.assert_allclose(back.front_probability(X), p, atol=1e-3)
    assert SideClassifier.from_arrays({"other": np.zeros(1)}) is None
    # large inputs saturate; inputs it cannot evaluate give no evidence (0.5), never NaN
    assert clf.front_probability(np.full((1, 6), 1e30))[0] > 0.99
    assert clf.front_probability(np.full((2, 6), [[np.inf], [np.nan]]))[0] == 0.5
    assert clf.front_probability(np.full((2, 6), [[np.inf], [np.nan]]))[1] == 0.5


@pytest.mark.parametrize("tamper, message", [
    (lambda a: a.pop("side_net_W1"), "incomplete"),
    (lambda a: a.update(side_net_W9=np.zeros((1, 1))), "do not declare"),
    (lambda a: a.update(side_net_layers=np.int64(0)), "layers"),
    (lambda a: a.update(side_net_layers=np.float64(2)), "layers"),
    (lambda a: a.update(side_net_W1=np.zeros((2, 2), np.float16),
                        side_net_b1=np.zeros(2, np.float32)), "not one logit"),
    (lambda a: a.update(side_net_W0=np.zeros((5, 2), np.float16)), "shape"),
    (lambda a: a.update(side_net_b0=np.array([np.nan, 0.0], np.float32)), "not finite"),
    (lambda a: a.update(side_net_input_scale=np.float64(0.0)), "positive"),
    (lambda a: a.update(side_net_input_scale=np.zeros(2)), "one number"),
    (lambda a: a.update(side_net_W0=np.array([["x", "y"]] * 6)), "floats"),
    (lambda a: a.update(side_net_W0=np.full((6, 2), 1e300)), "float32 range"),
    (lambda a: a.pop("side_net_layers"), "incomplete"),
    (lambda a: a.update(side_net_input_scale=np.float64(1e-300)), "typical inputs"),
    (lambda a: a.update(side_net_input_mean=np.full(6, 1e300)), "typical inputs"),
    (lambda a: a.update(side_net_W0=np.zeros((6, 0), np.float16), side_net_b0=np.zeros(0),
                        side_net_W1=np.zeros((0, 1), np.float16)), "no units"),
])
def test_a_tampered_classifier_is_refused_with_a_named_problem(tamper, message):
    arrays = side_classifier_arrays(_classifier())
    tamper(arrays)
    with pytest.raises(ValueError, match=message):
        SideClassifier.from_arrays(arrays)


def test_fitting_learns_a_separable_side():
    pytest.importorskip("sklearn")
    from regressor.side_classifier_training import fit_side_classifier
    rng = np.random.default_rng(0)
    X = rng.normal(size=(2000, 5))
    heading = np.where(X[:, 1] > 0, 20.0, 160.0) + rng.normal(0, 5, 2000)
    clf = fit_side_classifier(X, heading, hidden=(16,), seed=0)
    Xt = rng.normal(size=(200, 5))
    assert np.mean((clf.front_probability(Xt) > 0.5) == (Xt[:, 1] > 0)) > 0.9
    with pytest.raises(ValueError, match="both halves"):
        fit_side_classifier(X, np.zeros(2000))


def _body(heading_deg: float, seed: int = 7) -> np.ndarray:
    rng = np.random.default_rng(seed)
    v = np.concatenate([[0.0, 0.0], rng.uniform(-40, 40, 53)])
    v[0], v[1] = np.cos(np.radians(heading_deg)), np.sin(np.radians(heading_deg))
    return v


def test_canonical_hypotheses_are_the_member_and_its_flip_weighed_by_the_classifier():
    member = _body(20.0)                       # faces the camera's half
    raw = _body(20.0, seed=3)
    favoured = canonical_hypotheses(raw, member, front=0.97)
    assert favoured.canonical
    np.testing.assert_allclose(favoured.poses[0], member)      # raw's norm is 1 here
    np.testing.assert_allclose(favoured.poses[1], front_back_flip(member))
    # an ambiguous raw (low norm) makes an ambiguous pair: the filters and outputs see it
    low = raw.copy()
    low[:2] *= 0.2
    assert np.linalg.norm(canonical_hypotheses(low, member, 0.5).poses[:, :2], axis=1) == \
        pytest.approx([0.2, 0.2])
    assert favoured.log_evidence[0] > favoured.log_evidence[1]
    doubted = canonical_hypotheses(raw, member, front=0.03)
    assert doubted.log_evidence[0] - doubted.log_evidence[1] < \
        favoured.log_evidence[0] - favoured.log_evidence[1]
    # the main head's side does not count: the same member, the raw on the other side
    other = canonical_hypotheses(front_back_flip(raw), member, front=0.5)
    same = canonical_hypotheses(raw, member, front=0.5)
    np.testing.assert_allclose(same.log_evidence, other.log_evidence)
    # and the classifier at its overall rate says nothing either way
    assert same.log_evidence == pytest.approx([0.0, 0.0], abs=0.3)


def test_only_a_model_with_limbs_and_a_side_classifier_switches_canonically():
    class Plain:
        gives_canonical_pairs, canonical_priors, training_fps = False, None, 30.0

    class Canonical:
        gives_canonical_pairs, canonical_priors, training_fps = True, None, 30.0

    plain, canonical = chain_options(Plain()), chain_options(Canonical())
    assert plain["switch"] == SWITCH_PROBABILITY
    assert canonical["switch"] == CANONICAL_SWITCH_PROBABILITY
    # and weighs its evidence by the canonical chain's own exponent
    assert plain["evidence_weight"] == EVIDENCE_WEIGHT
    assert canonical["evidence_weight"] == CANONICAL_EVIDENCE_WEIGHT != EVIDENCE_WEIGHT


def test_the_joints_ambiguity_inflation_is_smaller_for_a_model_that_gives_canonical_pairs():
    """The canonical member commits to one body on ambiguous frames, the main head averages
    two: its joints' R is inflated less (TrackerSettings.joint_factor), unless set."""
    from tracker.pipeline import (AMBIGUOUS_JOINT_FACTOR, CANONICAL_AMBIGUOUS_JOINT_FACTOR,
                                  TrackerSettings, kalman_factory)

    class Model:
        gives_canonical_pairs = False
        process_noise = np.ones(54)
        measurement_covariance = np.eye(54)
        ambiguity_threshold = 0.5

    plain, canonical = Model(), Model()
    canonical.gives_canonical_pairs = True
    settings = TrackerSettings()
    assert settings.joint_factor(plain) == AMBIGUOUS_JOINT_FACTOR == 4.0
    assert settings.joint_factor(canonical) == CANONICAL_AMBIGUOUS_JOINT_FACTOR == 2.0
    assert TrackerSettings(ambiguous_joint_factor=3.0).joint_factor(canonical) == 3.0
    # the filters use it: the joints' R on an ambiguous frame
    for model, factor in ((plain, 4.0), (canonical, 2.0)):
        f = kalman_factory(model, settings)(FPS)
        assert f.R_ambiguous[5, 5] == pytest.approx(factor * f.R[5, 5])


def _backward_walker(classifier_right: float):
    """Walking away from the camera while facing it (heading 0) for 150 frames.
    The canonical member is the truth's flip for the first 40 frames, then the truth; the
    main head's pose is ambiguous (norm 0.1) and alternates sides, so it says nothing; the
    classifier gives the true member 0.95 on a share classifier_right of frames, 0.05 on the
    rest. Returns (filtered headings of the last 30 frames, smoothed headings), degrees."""
    T, rng = 150, np.random.default_rng(5)
    truth = _body(0.0)
    bank = FrontBackTracker(lambda fps: PoseKalmanFilter(fps), FPS,
                            switch=CANONICAL_SWITCH_PROBABILITY)
    out = []
    with threadpool_limits(limits=1, user_api="blas"):
        for t in range(T):
            true = truth + np.concatenate([[0, 0], rng.normal(0, 3, 53)])
            member = front_back_flip(true) if t < 40 else true
            raw = true if t % 2 else front_back_flip(true)
            raw[:2] *= 0.1
            p_true = 0.95 if rng.random() < classifier_right else 0.05
            p_member = p_true if t >= 40 else 1 - p_true
            front = p_member if member[0] >= 0 else 1 - p_member
            out.append(bank.step(canonical_hypotheses(raw, member, front)))
    return (np.array([pose_angles(d.filtered)[0] for d in out[-30:]]),
            pose_angles(bank.smoothed())[:, 0])


@pytest.mark.slow
def test_a_backward_walker_is_turned_the_right_way_by_the_classifier():
    """A classifier right on 75 % of frames turns the chain the right way after 40 wrong
    frames; inverted (right on 25 %), it holds the wrong way: the classifier decides."""
    late, smoothed = _backward_walker(0.75)
    assert np.all(np.abs(wrap_deg(late)) < 30.0)
    assert np.mean(np.abs(wrap_deg(smoothed)) < 30.0) > 0.9
    late, smoothed = _backward_walker(0.25)
    assert np.all(np.abs(wrap_deg(late)) > 150.0)
    assert np.mean(np.abs(wrap_deg(smoothed)) < 30.0) < 0.1


def test_a_mixture_model_with_limbs_and_a_side_classifier_proposes_canonical_pairs(tmp_path):
    """Saved and loaded with the model; refused without limbs or for another input length;
    the tracker's hypotheses become the limbs' member and its flip."""
    pytest.importorskip("sklearn")
    from test_mixture import _mixture_model, assert_refused_when_changed
    from regressor.limb_net_training import fit_limb_net
    from regressor.model_file import load_model
    from regressor.pose_model import PoseModelError, load_pose_model
    from regressor.model_writer import save_pose_model
    from tracker.tracks.proposals import propose_batch
    model, x = _mixture_model()                              # input length 8
    rng = np.random.default_rng(3)
    targets = np.column_stack([np.ones(len(x)), np.zeros(len(x)),
                               wrap_deg(40 * np.tanh(x[:, :1]) + rng.normal(0, 1, (len(x), 53)))])
    model.side_classifier = _classifier(P=8)
    assert not model.gives_canonical_pairs and model.hypotheses(x[:2], 2).front is None
    with pytest.raises(PoseModelError, match="needs the model's limbs"):
        save_pose_model(tmp_path / "nolimbs.npz", model)
    model.limb_net = fit_limb_net(x, targets, np.zeros(53), np.eye(55)[0], members=1,
                                  hidden=(8,), max_iter=20)
    assert model.gives_canonical_pairs
    estimates = model.hypotheses(x[:5], 2)
    poses, limbs, front = estimates.poses, estimates.limbs, estimates.front
    np.testing.assert_allclose(front, model.side_classifier.front_probability(x[:5]))
    hyps = propose_batch(model, x[:5])
    assert all(h.canonical and len(h.poses) == 2 for h in hyps)
    # the member's body angles and heading direction, with the main head's norm (ambiguity)
    np.testing.assert_allclose(hyps[0].poses[0, 2:], limbs[0, 2:])
    direction = hyps[0].poses[0, :2] / np.linalg.norm(hyps[0].poses[0, :2])
    np.testing.assert_allclose(direction, limbs[0, :2] / np.linalg.norm(limbs[0, :2]))
    assert np.linalg.norm(hyps[0].poses[0, :2]) == pytest.approx(np.linalg.norm(poses[0, 0, :2]))
    assert chain_options(model)["switch"] == CANONICAL_SWITCH_PROBABILITY
    # the tracker's chains (built by one helper) take the canonical switch rates and weight
    chain = front_back_tracker(model, 30.0)
    assert chain.switch == CANONICAL_SWITCH_PROBABILITY
    assert chain.evidence_weight == CANONICAL_EVIDENCE_WEIGHT
    path = tmp_path / "side.npz"
    save_pose_model(path, model)
    loaded = load_pose_model(path)
    np.testing.assert_allclose(loaded.hypotheses(x[:5], 2).front, front, atol=1e-3)
    limb_parts = [k for k in load_model(path).parts if k.startswith("limb_net_")]
    assert_refused_when_changed(path, [(dict.fromkeys(limb_parts), "needs the model's limbs"),
                                       (side_classifier_arrays(_classifier(P=5)), "takes 5 inputs"),
                                       ({"side_net_b1": None}, "side classifier is incomplete")])


def test_only_a_mixture_carries_a_side_classifier(tmp_path):
    from test_mixture import assert_only_a_mixture_carries
    clf = _classifier()
    assert_only_a_mixture_carries(tmp_path, "side_classifier", clf, side_classifier_arrays(clf))


def test_canonical_statistics_count_the_true_member_its_switches_and_the_classifier():
    """Hand-made renders: the member is the truth for 30 frames, then its flip for 30; the
    classifier gives the true member 0.95."""
    from lab.hypothesis_priors import canonical_statistics
    truth = np.array([_body(20.0)] * 60)
    hyps = []
    for t in range(60):
        member = truth[t] if t < 30 else front_back_flip(truth[t])
        p_true = 0.95
        front = p_true if (t < 30) == (member[0] >= 0) else 1 - p_true
        hyps.append(canonical_hypotheses(truth[t], member, front))
    stats = canonical_statistics({"one": {"hypotheses": hyps, "truth": truth}})
    assert stats["canonical_overall"] == pytest.approx(0.5)
    assert stats["switch_probability"] == [pytest.approx(1 / 30, abs=1e-3), 0.0]
    assert stats["by_front"][-1] == 1.0 and stats["frames_by_front"][-1] == 30
    assert stats["by_front"][0] == 0.0 and stats["frames_by_front"][0] == 30
