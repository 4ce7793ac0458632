"""Sparse relevance vector machine over k-means candidate kernels (Tipping 2001; one relevance
set for all K outputs): T = 1 b^T + B W + E, B (N, M) Gaussian kernels on M k-means centres of
the inputs, centred and scaled to unit-norm columns; row i of W ~ N(0, I_K / alpha_i); E ~ N(0,
1/beta). The fit (Tipping & Faul's sequential sparse Bayesian learning) is in
regressor.sparse_rvm_fit. A new observation's variance, per row (the same for every output when
output_scale is "common": a measurement noise for a Kalman filter):
    sigma^2(x) = y_scale^2 (1/beta + 1/(N beta) + b(x)^T Sigma b(x)),
b(x) the kept centres' centred, scaled kernels, Sigma their weights' posterior covariance.
"""
from __future__ import annotations

import numpy as np

from .basis import centre_squares, gaussian_design, validate_X
from .basis_regressor import BasisRegressor


class SparseRVMRegressor(BasisRegressor):
    """Multi-output sparse RVM on Gaussian kernels at k-means centres, fitted in candidate space.

    n_candidates: candidate kernels M (the fit's cost, after one pass over the rows, depends on
    M, not on the rows). width: kernel width in input units, None: regressor.basis_fit's
    default_width with width_scale. noise: 1/beta as a fraction of the scaled output variance,
    None: estimated. output_scale: "each" (unit variance per output) or "common" (one scale, so
    the noise measures a Euclidean error), as in regressor.rvm. min_gain: nats charged per kept
    kernel (0: the plain RVM). max_iter, tol: steps, stopping when none gains tol nats. seed:
    the candidates' k-means. Learned: candidates_ (M, D), relevance_ (R,) kept candidates,
    centres_ (R, D), width_, coef_ (R, K), intercept_ (K,), alpha_ (R,), beta_ (scaled
    outputs), noise_ (K,) output units, sigma_ (R, R) (scaled), phi_mean_ (R,), y_scale_ (K,),
    n_train_, log_marginal_likelihood_, n_iter_, converged_, n_features_in_.
    """

    def __init__(self, n_candidates: int = 200, width: float | None = None,
                 width_scale: float = 0.5, noise: float | None = None, output_scale: str = "each",
                 min_gain: float = 0.0, max_iter: int = 3000, tol: float = 0.01, seed: int = 0):
        self.n_candidates = n_candidates
        self.width = width
        self.width_scale = width_scale
        self.noise = noise
        self.output_scale = output_scale
        self.min_gain = min_gain
        self.max_iter = max_iter
        self.tol = tol
        self.seed = seed

    def fit(self, X, y):
        """Fit on X (N, D) and y (N,) or (N, K) (regressor.sparse_rvm_fit); returns self."""
        from .sparse_rvm_fit import fit_sparse_rvm
        return fit_sparse_rvm(self, X, y)

    def predict(self, X, return_std: bool = False):
        """Mean (N, K) for X (N, D), (N,) if fitted on a 1-D y; with return_std, also the
        standard deviation of a new observation (same shape, output units), module docstring."""
        self._check_fitted()
        X = validate_X(X, self.n_features_in_, owner=type(self).__name__)
        Phi = gaussian_design(X, self.centres_, self.width_, centre_squares(self, self.centres_))
        Y = Phi @ self.coef_ + self.intercept_
        if not return_std:
            return Y[:, 0] if self._y_1d else Y
        Bx = Phi - self.phi_mean_
        var = (1.0 + 1.0 / self.n_train_) / self.beta_ + ((Bx @ self.sigma_) * Bx).sum(1)
        std = np.sqrt(var)[:, None] * self.y_scale_
        return (Y[:, 0], std[:, 0]) if self._y_1d else (Y, std)
