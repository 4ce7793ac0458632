"""Sparse RVM fitted in candidate space (regressor.sparse_rvm) on synthetic data with known structure."""
import numpy as np
import pytest

import regressor.sparse_rvm_fit as sparse_rvm_fit
from regressor.basis import RegressorInputError, gaussian_design
from regressor.sparse_rvm import SparseRVMRegressor


def _kernel_data(n=200, K=4, noise=0.01, seed=0):
    """x (n, 2) on a grid-free scatter; y (n, K) a sum of 3 Gaussian kernels of width 1.5
    centred on three of the rows, with one weight row per kernel shared by the K outputs."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-5, 5, (n, 2))
    true = np.array([3, n // 3, 2 * n // 3])
    W = rng.normal(0, 1, (3, K)) + np.sign(rng.normal(size=(3, K)))
    y = gaussian_design(x, x[true], 1.5) @ W + 0.5 + noise * rng.normal(size=(n, K))
    return x, y, true, W


def test_fast_sbl_recovers_a_sparse_ground_truth():
    x, y, true, W = _kernel_data()
    # Candidates are the rows themselves (n_candidates >= n); a BIC-like cost per kernel; one
    # scale for all outputs, so that the one noise level is every output's.
    model = SparseRVMRegressor(n_candidates=200, width=1.5, min_gain=0.5 * 4 * np.log(200),
                               output_scale="common").fit(x, y)
    assert model.converged_
    np.testing.assert_array_equal(np.sort(model.centres_, axis=0), np.sort(x[true], axis=0))
    order = [int(np.flatnonzero((model.centres_ == c).all(1))[0]) for c in x[true]]
    np.testing.assert_allclose(model.coef_[order], W, atol=0.05)
    assert model.noise_ == pytest.approx(np.full(4, 1e-4), rel=0.3)


def test_plain_sbl_on_kmeans_candidates_keeps_few_of_them_and_fits():
    x, y, _, _ = _kernel_data(n=400, noise=0.05, seed=1)
    truth = _kernel_data(n=400, noise=0.0, seed=1)[1]
    model = SparseRVMRegressor(n_candidates=150, width=1.5).fit(x, y)   # min_gain 0: plain ML-II
    assert model.n_basis_ < 150 / 4
    assert np.abs(model.predict(x) - truth).max() < 0.1


def _direct_log_marginal_likelihood(model, x, y):
    """log N(T; 0, I/beta + B A^-1 B^T) summed over outputs, in row space (N x N)."""
    Phi = gaussian_design(x, model.centres_, model.width_)
    B = Phi - Phi.mean(0)
    B /= np.sqrt((B * B).sum(0))
    T = (y - y.mean(0)) / model.y_scale_
    C = np.eye(len(x)) / model.beta_ + (B / model.alpha_) @ B.T
    L = np.linalg.cholesky(C)
    Z = np.linalg.solve(L, T)
    N, K = T.shape
    return -0.5 * (K * (N * np.log(2 * np.pi) + 2 * np.log(np.diag(L)).sum()) + (Z * Z).sum())


@pytest.mark.slow
def test_log_marginal_likelihood_never_falls_over_the_steps():
    rng = np.random.default_rng(3)
    x = np.sort(rng.uniform(-10, 10, 150))[:, None]
    y = np.column_stack([np.sinc(x[:, 0] / np.pi), np.cos(x[:, 0] / 3)]) + 0.1 * rng.normal(size=(150, 2))
    values = []
    for steps in range(1, 60, 3):      # noise re-estimated too (every 50 steps and at the end)
        model = SparseRVMRegressor(n_candidates=40, width=2.0, max_iter=steps).fit(x, y)
        values.append(model.log_marginal_likelihood_)
        assert model.log_marginal_likelihood_ == pytest.approx(
            _direct_log_marginal_likelihood(model, x, y), abs=1e-6)
    assert np.all(np.diff(values) >= -1e-9)
    assert values[-1] > values[0] + 100


def test_predictive_std_grows_away_from_the_data():
    rng = np.random.default_rng(4)
    x = rng.uniform(-5, 5, (300, 1))
    y = np.sin(x[:, 0]) + 0.1 * rng.normal(size=300)
    model = SparseRVMRegressor(n_candidates=50, width=1.5).fit(x, y)
    _, std_data = model.predict(x, return_std=True)
    _, std_far = model.predict(np.array([[-15.0], [15.0]]), return_std=True)
    assert std_data.shape == (300,)
    assert std_far.min() > std_data.max()
    assert std_data.min() >= np.sqrt(model.noise_[0])        # never below the noise itself
    # The mean prediction is unchanged by asking for the standard deviation.
    np.testing.assert_array_equal(model.predict(x), model.predict(x, return_std=True)[0])


def test_one_relevance_set_serves_every_output():
    rng = np.random.default_rng(5)
    x = rng.uniform(-5, 5, (300, 2))
    a, b = 20, 200                                            # output 0 needs kernel a, output 1 kernel b
    K = gaussian_design(x, x[[a, b]], 1.5)
    y = np.column_stack([2 * K[:, 0], -3 * K[:, 1], np.zeros(300)]) + 0.05 * rng.normal(size=(300, 3))
    settings = dict(n_candidates=300, width=1.5, output_scale="common", min_gain=0.5 * 3 * np.log(300))
    model = SparseRVMRegressor(**settings).fit(x, y)
    np.testing.assert_array_equal(np.sort(model.centres_, axis=0), np.sort(x[[a, b]], axis=0))
    assert model.coef_.shape == (2, 3)
    assert np.abs(model.coef_[:, 2]).max() < 0.05            # nothing for the pure-noise output
    mean, std = model.predict(x[:5], return_std=True)
    assert mean.shape == std.shape == (5, 3)
    np.testing.assert_allclose(std, np.repeat(std[:, :1], 3, axis=1))   # one noise ("common")
    alone = SparseRVMRegressor(**settings).fit(x, y[:, 0])
    np.testing.assert_array_equal(alone.centres_, x[[a]])   # one output alone: its kernel only


def test_statistics_in_blocks_equal_the_whole_matrix(monkeypatch):
    rng = np.random.default_rng(7)
    x, T = rng.normal(size=(50, 3)), rng.normal(size=(50, 2))
    T -= T.mean(0)
    centres = rng.normal(size=(8, 3))
    monkeypatch.setattr(sparse_rvm_fit, "_CHUNK", 7)
    mean, G, BtT = sparse_rvm_fit.sufficient_statistics(x, T, centres, 2.0)
    Phi = gaussian_design(x, centres, 2.0)
    B = Phi - Phi.mean(0)
    np.testing.assert_allclose(mean, Phi.mean(0))
    np.testing.assert_allclose(G, B.T @ B, atol=1e-12)
    np.testing.assert_allclose(BtT, B.T @ T, atol=1e-12)


@pytest.mark.parametrize("option", [dict(n_candidates=0), dict(noise=-1.0), dict(min_gain=-1.0),
                                    dict(output_scale="all"), dict(width=0.0)])
def test_bad_options_are_refused_by_name(option):
    x, y, _, _ = _kernel_data(n=30)
    with pytest.raises(RegressorInputError, match=next(iter(option))):
        SparseRVMRegressor(**option).fit(x, y)


def test_predictions_keep_the_centres_squares_bit_for_bit_and_follow_new_centres():
    """The kernel experts and the gate keep their centres' squared norms between predictions
    (regressor.basis.centre_squares): the same design matrix as computing them each time, new
    ones for new centres, and predict leaves the estimator's attributes as they were."""
    from regressor.basis import centre_squares, gaussian_design
    rng = np.random.default_rng(5)
    X, y = rng.normal(size=(80, 3)), rng.normal(size=(80, 2))
    est = SparseRVMRegressor(n_candidates=20).fit(X, y)
    attributes = dict(vars(est))
    first = est.predict(X[:7])
    assert vars(est).keys() == attributes.keys()
    np.testing.assert_array_equal(est.predict(X[:7]), first)
    np.testing.assert_array_equal(
        gaussian_design(X, est.centres_, est.width_, centre_squares(est, est.centres_)),
        gaussian_design(X, est.centres_, est.width_))
    est.centres_ = est.centres_ * 2.0                      # a new array: new squares
    np.testing.assert_array_equal(centre_squares(est, est.centres_),
                                  (est.centres_ ** 2).sum(1))
