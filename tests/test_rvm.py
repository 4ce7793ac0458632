"""RVM with a columnwise prior: sparsity on synthetic data with known structure."""
import numpy as np
import pytest

from regressor.dls import DLSRegressor
from regressor.rvm import RVMRegressor


def test_linear_rvm_recovers_the_relevant_features_for_all_outputs():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(300, 40))
    true = [3, 17, 29]
    W = np.zeros((40, 5))
    W[true] = rng.normal(size=(3, 5)) * 3
    Y = X @ W + 2.0 + 0.1 * rng.normal(size=(300, 5))
    bic_cost = 0.5 * 5 * np.log(300)   # nats per kept feature; plain ML-II keeps ~40% of noise features
    model = RVMRegressor(basis="linear", min_gain=bic_cost).fit(X, Y)
    assert model.converged_
    assert sorted(model.relevance_.tolist()) == true
    np.testing.assert_allclose(model.coef_, W[true], atol=0.05)
    np.testing.assert_allclose(model.intercept_, 2.0, atol=0.05)
    assert model.noise_ == pytest.approx(np.full(5, 0.01), rel=0.3)


def test_kernel_rvm_fits_sinc_with_few_relevance_vectors():
    rng = np.random.default_rng(1)
    x = np.sort(rng.uniform(-10, 10, 200))[:, None]
    y = np.sinc(x[:, 0] / np.pi) + 0.05 * rng.normal(size=200)
    model = RVMRegressor(basis="gaussian", width=2.0).fit(x, y)
    grid = np.linspace(-10, 10, 400)[:, None]
    assert model.n_basis_ <= 20
    assert np.abs(model.predict(grid) - np.sinc(grid[:, 0] / np.pi)).max() < 0.1
    np.testing.assert_array_equal(model.centres_, x[model.relevance_])


def test_min_gain_trades_relevance_vectors_for_fit():
    rng = np.random.default_rng(2)
    x = rng.uniform(-10, 10, (300, 1))
    y = np.sinc(x[:, 0] / np.pi) + 0.05 * rng.normal(size=300)
    plain = RVMRegressor(width=1.0).fit(x, y)
    costly = RVMRegressor(width=1.0, min_gain=50.0).fit(x, y)
    assert costly.n_basis_ < plain.n_basis_


def test_one_relevance_set_serves_every_output():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(200, 20))
    Y = np.column_stack([X[:, 0] * 2, X[:, 5] - X[:, 0], np.zeros(200)]) + 0.05 * rng.normal(size=(200, 3))
    model = RVMRegressor(basis="linear", min_gain=0.5 * 3 * np.log(200)).fit(X, Y)
    assert sorted(model.relevance_.tolist()) == [0, 5]
    assert model.coef_.shape == (2, 3)


def test_rvm_predictions_match_dls_on_the_same_sparse_problem():
    rng = np.random.default_rng(4)
    X = rng.normal(size=(200, 10))
    Y = X[:, :2] @ np.array([[1.0, -1.0], [0.5, 2.0]]) + 0.01 * rng.normal(size=(200, 2))
    rvm = RVMRegressor(basis="linear").fit(X, Y)
    dls = DLSRegressor(basis="linear", lam=1e-8).fit(X, Y)
    np.testing.assert_allclose(rvm.predict(X), dls.predict(X), atol=0.01)


@pytest.mark.slow
def test_kernel_rvm_on_the_paper_data_is_sparse_and_beats_ridge(ankur_mat):
    import scipy.io

    from regressor.metrics import mean_point_error
    d = scipy.io.loadmat(ankur_mat)
    X, Y, Xt, Yt = np.sqrt(d["Y"][::2]), d["Z"][::2], np.sqrt(d["Y_test"]), d["Z_test"]
    rvm = RVMRegressor("gaussian", noise=0.05, width_scale=0.5, output_scale="common", min_gain=200.0).fit(X, Y)
    linear = DLSRegressor("linear", lam=0.1).fit(X, Y)
    assert rvm.n_basis_ < 0.15 * len(X)
    assert mean_point_error(rvm.predict(Xt), Yt) < 0.85 * mean_point_error(linear.predict(Xt), Yt)
