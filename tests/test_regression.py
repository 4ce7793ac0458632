"""DLS (ridge) regressor and the bases: exactness, offset, kernel width, input errors."""
import numpy as np
import pytest

from regressor.basis import NotFittedError, RegressorInputError, squared_distances
from regressor.basis_fit import default_width
from regressor.dls import DLSRegressor


def test_dls_is_exact_on_noise_free_linear_data():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(200, 6))
    W, b = rng.normal(size=(6, 3)), rng.normal(size=3)
    model = DLSRegressor(basis="linear", lam=1e-10).fit(X, X @ W + b)
    np.testing.assert_allclose(model.coef_, W, atol=1e-6)
    np.testing.assert_allclose(model.intercept_, b, atol=1e-6)


def test_dls_damping_shrinks_weights_but_not_offset():
    rng = np.random.default_rng(1)
    X = rng.normal(size=(100, 4))
    y = X @ np.ones(4) + 50.0
    strong = DLSRegressor(lam=1e3).fit(X, y)
    assert np.abs(strong.coef_).max() < 0.1
    assert abs(strong.intercept_[0] - 50.0) < 1.0
    assert strong.predict(X).shape == (100,)


def test_default_width_is_mean_pairwise_squared_distance():
    rng = np.random.default_rng(2)
    X = rng.normal(size=(50, 3))
    mean_sq = squared_distances(X, X).sum() / 50 ** 2
    assert default_width(X, 0.5) == pytest.approx(np.sqrt(0.5 * mean_sq))


def test_gaussian_dls_fits_a_smooth_function():
    x = np.linspace(-5, 5, 200)[:, None]
    y = np.sin(x[:, 0])
    model = DLSRegressor(basis="gaussian", lam=1e-6, width_scale=0.05).fit(x, y)
    assert np.abs(model.predict(x) - y).max() < 0.05


def test_bad_input_raises_with_shapes_in_message():
    model = DLSRegressor().fit(np.eye(4), np.arange(4.0))
    with pytest.raises(RegressorInputError, match="3 features"):
        model.predict(np.ones((2, 3)))
    with pytest.raises(RegressorInputError, match="NaN"):
        DLSRegressor().fit(np.full((3, 2), np.nan), np.zeros(3))
    with pytest.raises(RegressorInputError, match="basis"):
        DLSRegressor(basis="cubic").fit(np.eye(3), np.zeros(3))
    with pytest.raises(NotFittedError):
        DLSRegressor().predict(np.eye(3))


def test_get_set_params_round_trip():
    model = DLSRegressor(basis="gaussian", lam=0.5)
    assert model.get_params()["lam"] == 0.5
    assert model.set_params(lam=2.0) is model and model.lam == 2.0
    with pytest.raises(RegressorInputError, match="no parameter"):
        model.set_params(alpha=1)
