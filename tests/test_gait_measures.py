"""Gait measures (sequences.gait_measures) on hand-made knee sinusoids with known answers."""
from __future__ import annotations

import numpy as np
import pytest

from sequences.gait_measures import best_of, gait_measures, knee_flexion, swapped
from sequences.measures import MeasureError
from sequences.pose_vector import POSE_DIM, pose_vector_names

NAMES = pose_vector_names()
T = 120


def _walk(amplitude: float = 30.0, mean: float = 25.0) -> np.ndarray:
    """Knee flexion (T, 2) of a walk: the two knees half a cycle apart (correlation -1)."""
    phase = np.linspace(0, 4 * 2 * np.pi, T, endpoint=False)
    return np.stack([mean + amplitude * np.sin(phase),
                     mean + amplitude * np.sin(phase + np.pi)], axis=1)


def _gait_with_timing() -> np.ndarray:
    """A walk whose mean flexion also moves (twice per cycle), so timing is defined."""
    phase = np.linspace(0, 4 * 2 * np.pi, T, endpoint=False)
    return _walk() + 10 * np.cos(2 * phase)[:, None]


def test_truth_against_itself_scores_perfectly():
    truth = _gait_with_timing()
    m = gait_measures(truth, truth)
    assert m["timing"] == pytest.approx(1.0)
    assert m["alternation"] == pytest.approx(1.0)
    assert m["range"] == pytest.approx(1.0)
    assert m["lr_corr"] == pytest.approx(m["truth_lr_corr"])


def test_swapped_legs_alternate_backwards_with_perfect_timing_and_range():
    truth = _gait_with_timing()
    m = gait_measures(swapped(truth), truth)
    assert m["timing"] == pytest.approx(1.0)
    assert m["alternation"] == pytest.approx(-1.0)
    assert m["range"] == pytest.approx(1.0)


def test_averaged_legs_lose_alternation_and_range():
    """Both knees at the mean of the two configurations: they bend together, over the mean
    series' own range only."""
    truth = _walk()
    mean = truth.mean(axis=1, keepdims=True)
    est = np.repeat(mean, 2, axis=1)
    m = gait_measures(est, truth)
    assert m["alternation"] == 0.0                     # a constant difference does not vary
    assert m["range"] == pytest.approx(0.0, abs=1e-9)  # a pure walk's mean does not move
    blend = 0.75 * truth + 0.25 * swapped(truth)       # a quarter of the other configuration
    m = gait_measures(blend, truth)
    assert m["alternation"] == pytest.approx(1.0)
    assert m["range"] == pytest.approx(0.5)            # (0.75 - 0.25) of the amplitude
    assert m["truth_lr_corr"] == pytest.approx(-1.0)
    assert m["lr_corr"] == pytest.approx(-1.0)


def test_knees_bending_together_correlate_positively():
    truth = _walk()
    est = np.stack([truth[:, 0], truth[:, 0]], axis=1)     # the right knee copies the left
    m = gait_measures(est, truth)
    assert m["lr_corr"] == pytest.approx(1.0)
    assert m["truth_lr_corr"] == pytest.approx(-1.0)
    assert m["alternation"] == 0.0


def test_range_is_the_ratio_of_standard_deviations():
    truth = _walk(amplitude=30.0)
    est = _walk(amplitude=12.0, mean=40.0)
    assert gait_measures(est, truth)["range"] == pytest.approx(0.4)


def test_best_of_picks_the_right_configuration_each_frame():
    truth = _walk()
    wrong = swapped(truth)
    # Each frame, the hypotheses in a random order: the oracle finds the true one.
    rng = np.random.default_rng(0)
    order = rng.integers(0, 2, T).astype(bool)
    cand = np.where(order[:, None, None], np.stack([truth, wrong], 1), np.stack([wrong, truth], 1))
    np.testing.assert_allclose(best_of(cand, truth), truth)
    # Hypotheses that both average the legs: the oracle cannot do better than them.
    mean = np.repeat(truth.mean(axis=1, keepdims=True), 2, axis=1)
    assert gait_measures(best_of(np.stack([mean, mean], 1), truth), truth)["range"] < 1e-9


def test_knee_flexion_of_a_pose_vector():
    v = np.zeros((3, POSE_DIM))
    v[:, 0] = 1.0
    v[:, NAMES.index("LeftLeg_z")] = [0.0, 30.0, 90.0]
    v[:, NAMES.index("RightLeg_z")] = [45.0, 0.0, 10.0]
    np.testing.assert_allclose(knee_flexion(v), [[0, 45], [30, 0], [90, 10]], atol=1e-3)


def test_bad_shapes_are_refused():
    with pytest.raises(MeasureError, match="shape"):
        gait_measures(np.zeros((10, 3)), np.zeros((10, 2)))
    with pytest.raises(MeasureError, match="shape"):
        gait_measures(np.zeros((9, 2)), np.zeros((10, 2)))
    with pytest.raises(MeasureError, match="NaN"):
        gait_measures(np.full((10, 2), np.nan), np.zeros((10, 2)))
    with pytest.raises(MeasureError, match="candidates"):
        best_of(np.zeros((10, 2)), np.zeros((10, 2)))
