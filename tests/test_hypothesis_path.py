"""The most probable chain of hypotheses (regressor.hypothesis_path) on hand-made sequences."""
from __future__ import annotations

import numpy as np
import pytest

from regressor.angles import wrap_deg
from conftest import load_script
from regressor.hypothesis_path import HypothesisPathError, most_probable_path, squared_steps

step_variance = load_script("reproduce_paper").step_variance


def _two_tracks(T=12):
    """Hypothesis 0 moves smoothly 0, 1, 2, ...; hypothesis 1 sits 10 away, on alternate
    sides, so following it means jumping by 20 every frame."""
    t = np.arange(T, dtype=float)
    smooth = t[:, None]
    jumpy = (t + np.where(t % 2 == 0, 10.0, -10.0))[:, None]
    return np.stack([smooth, jumpy], axis=1)                       # (T, 2, 1)


def test_without_continuity_each_frame_takes_its_best_hypothesis():
    rng = np.random.default_rng(0)
    poses, log_w = rng.normal(size=(30, 4, 3)), rng.normal(size=(30, 4))
    np.testing.assert_array_equal(most_probable_path(poses, log_w, 1.0, continuity=0.0),
                                  log_w.argmax(axis=1))


def test_a_smooth_chain_beats_hypotheses_that_each_frame_slightly_prefers():
    poses = _two_tracks()
    log_w = np.log(np.tile([0.4, 0.6], (12, 1)))                  # every frame prefers 1
    assert most_probable_path(poses, log_w, 1.0, continuity=0.0).tolist() == [1] * 12
    assert most_probable_path(poses, log_w, step_var=1.0).tolist() == [0] * 12
    # Strong enough evidence still wins over the steps: a huge step variance frees them.
    assert most_probable_path(poses, log_w, step_var=1e6).tolist() == [1] * 12


def test_one_frames_clear_evidence_carries_over_an_ambiguous_stretch():
    """A person whose front/back a single frame settles: frame 0 says hypothesis 1, the
    rest cannot tell (equal weights), and the chain keeps what frame 0 said."""
    T = 10
    poses = np.stack([np.zeros((T, 1)), np.full((T, 1), 5.0)], axis=1)
    log_w = np.zeros((T, 2))
    log_w[0] = np.log([0.05, 0.95])
    assert most_probable_path(poses, log_w, step_var=1.0).tolist() == [1] * T
    # The last frame contradicts: a jump of 5 costs 25 / 2 = 12.5, more than either end's
    # evidence (log 19 = 2.9), so the chain stays on one side; at a step variance of 10 the
    # jump costs 1.25 and the chain makes it, once.
    log_w[-1] = np.log([0.95, 0.05])
    assert len(set(most_probable_path(poses, log_w, step_var=1.0).tolist())) == 1
    path = most_probable_path(poses, log_w, step_var=10.0)
    assert path[0] == 1 and path[-1] == 0 and np.count_nonzero(np.diff(path)) == 1


def test_the_chain_restarts_where_a_new_sequence_begins():
    T = 10
    poses = np.stack([np.zeros((T, 1)), np.full((T, 1), 5.0)], axis=1)
    log_w = np.zeros((T, 2))
    log_w[0] = np.log([0.9, 0.1])
    log_w[5] = np.log([0.2, 0.8])         # too weak to pay for a jump of 5 within a sequence
    assert most_probable_path(poses, log_w, step_var=1.0).tolist() == [0] * T
    ids = np.repeat([7, 8], 5)
    assert most_probable_path(poses, log_w, 1.0, sequence_ids=ids).tolist() == [0] * 5 + [1] * 5
    # Each piece traced back from its own best end: the first one's is hypothesis 1 here.
    log_w[0], log_w[5] = np.log([0.1, 0.9]), np.log([0.8, 0.2])
    assert most_probable_path(poses, log_w, 1.0, sequence_ids=ids).tolist() == [1] * 5 + [0] * 5


def test_angle_steps_wrap_round_the_circle():
    """Hypothesis 0 turns steadily through +-180 degrees (10 a frame); hypothesis 1 jumps
    between 110 and 130 and the frames prefer it slightly. As angles the turn is the smooth
    chain; unwrapped, it would look like a 340-degree jump the chain must avoid."""
    t = np.arange(8)
    turning = wrap_deg(150.0 + 10.0 * t)                        # 150 ... 180, -170 ... -140
    poses = np.stack([turning, np.where(t % 2 == 0, 110.0, 130.0)], axis=1)[:, :, None]
    log_w = np.log(np.tile([0.45, 0.55], (8, 1)))
    assert most_probable_path(poses, log_w, 100.0, angles_deg=True).tolist() == [0] * 8
    assert most_probable_path(poses, log_w, 100.0).tolist() != [0] * 8
    assert squared_steps(np.array([[179.0]]), np.array([[-179.0]]), angles_deg=True)[0, 0] \
        == pytest.approx(4.0)


def test_step_variance_is_the_mean_squared_step_within_sequences():
    Y = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0], [50.0, 50.0], [50.0, 51.0]])
    assert step_variance(Y[:3]) == pytest.approx((1 + 4) / 2)
    assert step_variance(Y, sequence_ids=[0, 0, 0, 1, 1]) == pytest.approx((1 + 4 + 1) / 3)


def test_bad_inputs_are_refused_with_the_reason():
    poses, log_w = np.zeros((5, 2, 3)), np.zeros((5, 2))
    with pytest.raises(HypothesisPathError, match="log_weight"):
        most_probable_path(poses, np.zeros((5, 3)), 1.0)
    with pytest.raises(HypothesisPathError, match="step_var"):
        most_probable_path(poses, log_w, 0.0)
    with pytest.raises(HypothesisPathError, match="continuity"):
        most_probable_path(poses, log_w, 1.0, continuity=-1.0)
    with pytest.raises(HypothesisPathError, match="sequence_ids"):
        most_probable_path(poses, log_w, 1.0, sequence_ids=[0, 0, 1])
    with pytest.raises(HypothesisPathError, match="sequence_ids"):
        most_probable_path(np.zeros((4, 2, 3)), np.zeros((4, 2)), 1.0,
                           sequence_ids=np.zeros((2, 2)))
    with pytest.raises(HypothesisPathError, match="T, M >= 1"):
        most_probable_path(np.zeros((5, 0, 3)), np.zeros((5, 0)), 1.0)
    with pytest.raises(HypothesisPathError, match="finite"):
        most_probable_path(np.full((5, 2, 3), np.nan), log_w, 1.0)
    with pytest.raises(HypothesisPathError, match="NaN"):
        most_probable_path(poses, np.full((5, 2), np.nan), 1.0)
    with pytest.raises(HypothesisPathError, match="non-finite"):
        step_variance(np.array([[0.0], [np.nan]]))
    with pytest.raises(HypothesisPathError, match="never change"):
        step_variance(np.ones((4, 2)))
    with pytest.raises(HypothesisPathError, match="one sequence"):
        step_variance(np.ones((3, 2)), sequence_ids=[0, 1, 2])
