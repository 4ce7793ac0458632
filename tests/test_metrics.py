"""Error and jitter measures on hand-made sequences with known answers."""
import numpy as np
import pytest

from regressor.metrics import (MetricInputError, acceleration_error, angle_jitter, angular_error,
                               contiguous_folds, mean_point_error, point_jitter, rms_per_angle)
from regressor.angles import wrap_deg


def test_mean_point_error_is_mean_euclidean_distance():
    true = np.zeros((2, 6))
    est = np.array([[3, 4, 0, 0, 0, 0], [0, 0, 0, 1, 0, 0]], float)   # distances (5, 0) and (0, 1)
    assert mean_point_error(est, true) == pytest.approx((2.5 + 0.5) / 2)


def test_point_jitter_of_uniform_motion_is_zero_and_of_a_kink_is_known():
    t = np.arange(5.0)[:, None]
    assert point_jitter(np.hstack([t, 2 * t, 0 * t])) == pytest.approx(0.0)
    P = np.zeros((3, 3))
    P[1, 0] = 1.0                                      # second difference (-2, 0, 0) at one frame
    assert point_jitter(P) == pytest.approx(2.0)


def test_angular_error_wraps_at_180():
    est = np.array([[179.0, 10.0]])
    true = np.array([[-179.0, 20.0]])
    assert angular_error(est, true) == pytest.approx((2.0 + 10.0) / 2)
    np.testing.assert_allclose(rms_per_angle(np.array([[170.0], [0.0]]), np.array([[-170.0], [0.0]])),
                               [np.sqrt(20.0 ** 2 / 2)])
    assert wrap_deg(540.0) == pytest.approx(180.0)     # the one convention: (-180, 180]


def test_angle_jitter_crossing_180_is_smooth():
    steady = np.array([[170.0], [-180.0], [-170.0]])        # +10 degrees per frame across +-180
    assert angle_jitter(steady) == pytest.approx(0.0)
    assert angle_jitter(np.array([[0.0], [10.0], [0.0], [10.0]])) == pytest.approx(20.0)


def test_acceleration_error_measures_the_jitter_of_the_error():
    true = np.linspace(-200, 200, 9)[:, None]
    assert acceleration_error(true + 30.0, true) == pytest.approx(0.0)
    est = true.copy()
    est[4] += 5.0
    assert acceleration_error(wrap_deg(est), wrap_deg(true)) == pytest.approx((5 + 10 + 5) / 7)


def test_bad_inputs_are_refused():
    with pytest.raises(MetricInputError, match="multiple of 3"):
        mean_point_error(np.zeros((2, 4)), np.zeros((2, 4)))
    with pytest.raises(MetricInputError, match="equal"):
        angular_error(np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(MetricInputError, match="NaN"):
        angle_jitter(np.full((3, 1), np.nan))
    with pytest.raises(MetricInputError, match="3 frames"):
        point_jitter(np.zeros((2, 3)))


def test_contiguous_folds_cover_everything_once():
    folds = contiguous_folds(10, 3)
    np.testing.assert_array_equal(np.concatenate(folds), np.arange(10))


def test_r2_score_is_scikit_learns_uniform_average_and_the_regressors_score():
    from sklearn.metrics import r2_score as sklearn_r2
    from regressor.dls import DLSRegressor
    from regressor.metrics import r2_score
    rng = np.random.default_rng(0)
    y = rng.normal(size=(40, 3))
    y[:, 2] = 1.5                                  # a constant output: 1 if exact, else 0
    predicted = y + rng.normal(scale=0.3, size=y.shape)
    assert r2_score(predicted, y) == pytest.approx(sklearn_r2(y, predicted))
    predicted[:, 2] = 1.5
    assert r2_score(predicted, y) == pytest.approx(sklearn_r2(y, predicted))
    model = DLSRegressor().fit(y[:, :2], y[:, 0])
    expected = sklearn_r2(y[:, 0], model.predict(y[:, :2]))
    assert model.score(y[:, :2], y[:, 0]) == pytest.approx(expected)
