"""The fit of regressor.sparse_rvm.SparseRVMRegressor, in candidate space (model: that module).

T is the outputs scaled as in regressor.rvm (``output_scale``); the offset b is unpenalised
(centring). Everything the fit needs is the sufficient statistics G = B^T B (M, M), B^T T (M, K)
and ||T||^2, accumulated once over the rows in chunks: O(N M^2) once, then every step of Tipping
& Faul's (2003) sequential algorithm (add, re-estimate or delete the one basis function with the
largest likelihood gain, regressor.rvm.step_gains) costs O(M R) for R active functions, whatever N.

Noise: ``noise`` fixes 1/beta (a fraction of the scaled output variance); None re-estimates beta
(the residual over N - sum gamma) whenever the steps stop and every ``_REFRESH`` steps, keeping a
new beta only when it raises the log marginal likelihood, so the likelihood never falls.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg

from .basis import RegressorInputError, gaussian_design
from .basis_fit import default_width, validate_Xy
from .mixture_fit import kmeans
from .rvm import _ALPHA_MAX, _BETA_MAX, _Stats, check_learning_options, step_gains

_REFRESH = 50          # steps between exact recomputations of the factors (and noise updates)
_CHUNK = 4096          # rows per block when accumulating the sufficient statistics


def candidate_centres(X: np.ndarray, n: int, seed: int) -> np.ndarray:
    """n candidate kernel centres (<= n, D) for rows X (N, D): k-means centres of X, or X itself
    when it has no more than n distinct rows."""
    if len(X) <= n:
        return np.unique(X, axis=0)
    return kmeans(X, n, seed=seed, iterations=10, sample=20000)


def sufficient_statistics(X: np.ndarray, T: np.ndarray, centres: np.ndarray, width: float):
    """Centred kernel statistics over rows X (N, D) with centred targets T (N, K).

    Returns phi_mean (M,), G = Bc^T Bc (M, M) and Bc^T T (M, K) for Bc the kernel matrix (N, M)
    minus its column means. Accumulated in blocks of rows about a provisional mean (the first
    block's) so that the N x M matrix is never held and the centring loses no precision.
    """
    N, M = len(X), len(centres)
    G, BtT, total = np.zeros((M, M)), np.zeros((M, T.shape[1])), np.zeros(M)
    shift = None
    for start in range(0, N, _CHUNK):
        P = gaussian_design(X[start:start + _CHUNK], centres, width)
        shift = P.mean(0) if shift is None else shift
        P -= shift
        total += P.sum(0)
        G += P.T @ P
        BtT += P.T @ T[start:start + _CHUNK]
    offset = total / N                                   # mean - shift
    G -= N * np.outer(offset, offset)
    return shift + offset, G, BtT                        # T is centred: BtT needs no correction


def log_marginal_likelihood(G_AA, BtT_A, TtT: float, N: int, K: int, alpha, beta: float) -> float:
    """log p(T | alpha, beta) of K independent outputs sharing alpha and beta, from statistics.

    G_AA (R, R), BtT_A (R, K) of the active functions, TtT = ||T||^2 summed over outputs:
    -1/2 [K (N log 2 pi - N log beta - sum log alpha + log|H|) + beta TtT - beta sum(BtT_A * Mu)],
    H = beta G_AA + diag(alpha), Mu = beta H^-1 BtT_A.
    """
    H = beta * G_AA
    H[np.diag_indices_from(H)] += alpha
    chol = scipy.linalg.cho_factor(H, lower=True, check_finite=False)
    Mu = beta * scipy.linalg.cho_solve(chol, BtT_A, check_finite=False)
    logdet = 2.0 * np.log(np.diag(chol[0])).sum()
    data = beta * TtT - beta * float((BtT_A * Mu).sum())
    return -0.5 * (K * (N * np.log(2 * np.pi) - N * np.log(beta) - np.log(alpha).sum() + logdet)
                   + data)


def _posterior(G_AA: np.ndarray, BtT_A: np.ndarray, alpha: np.ndarray, beta: float):
    """Sigma (R, R) and Mu (R, K) of the active weights."""
    H = beta * G_AA
    H[np.diag_indices_from(H)] += alpha
    Sigma = scipy.linalg.cho_solve(scipy.linalg.cho_factor(H, lower=True, check_finite=False),
                                   np.eye(len(alpha)), check_finite=False)
    return Sigma, beta * (Sigma @ BtT_A)


def better_beta(Gram, BtT, TtT: float, N: int, A, alpha, beta: float) -> float:
    """Noise precision re-estimated as K (N - sum gamma) / ||T - B_A Mu||^2 (MacKay), from the
    statistics alone; returned only if it raises the log marginal likelihood (else the geometric
    mean with the old one, if that does), otherwise the old beta."""
    K = BtT.shape[1]
    G_AA, BtT_A = Gram[np.ix_(A, A)], BtT[A]
    Sigma, Mu = _posterior(G_AA, BtT_A, alpha, beta)
    resid = TtT - 2.0 * float((BtT_A * Mu).sum()) + float((Mu * (G_AA @ Mu)).sum())
    gamma = 1.0 - alpha * np.diag(Sigma)
    new = min(K * max(N - float(gamma.sum()), 1e-6) / max(resid, 1e-300), _BETA_MAX)
    old_lml = log_marginal_likelihood(G_AA, BtT_A, TtT, N, K, alpha, beta)
    for candidate in (new, np.sqrt(new * beta)):
        if log_marginal_likelihood(G_AA, BtT_A, TtT, N, K, alpha, candidate) > old_lml:
            return float(candidate)
    return beta


def check_options(est) -> None:
    """Refuse (RegressorInputError, naming the option) a SparseRVMRegressor's bad options."""
    if not (int(est.n_candidates) == est.n_candidates and est.n_candidates >= 1):
        raise RegressorInputError(f"n_candidates={est.n_candidates!r}; expected a positive integer")
    if est.width is not None and not (np.isfinite(est.width) and est.width > 0):
        raise RegressorInputError(f"width={est.width!r}; expected a positive number or None")
    if not (np.isfinite(est.width_scale) and est.width_scale > 0):
        raise RegressorInputError(f"width_scale={est.width_scale!r}; expected a positive number")
    check_learning_options(est)


def fit_sparse_rvm(est, X, y):
    """Fit the SparseRVMRegressor est on X (N, D) and y (N,) or (N, K); returns est."""
    check_options(est)
    X, Y, est._y_1d = validate_Xy(X, y)
    N, K = Y.shape
    est.n_features_in_, est.n_train_ = X.shape[1], N
    y_mean, y_scale = Y.mean(0), Y.std(0)
    if est.output_scale == "common":
        y_scale = np.full(K, np.sqrt(np.mean(y_scale ** 2)))
    est.y_scale_ = np.where(y_scale > 0, y_scale, 1.0)
    T = (Y - y_mean) / est.y_scale_
    est.width_ = float(est.width) if est.width is not None else default_width(X, est.width_scale)
    est.candidates_ = candidate_centres(X, int(est.n_candidates), est.seed)
    phi_mean, G, BtT = sufficient_statistics(X, T, est.candidates_, est.width_)
    norms = np.sqrt(np.maximum(np.diag(G), 0.0))
    usable = np.flatnonzero(norms > 1e-9 * max(norms.max(), 1e-300))
    if len(usable) == 0:           # every kernel constant over the rows: the offset alone
        est.log_marginal_likelihood_, est.n_iter_, est.converged_ = np.nan, 0, True
        return _keep(est, usable, phi_mean, np.zeros(0), np.zeros((0, 0)), np.zeros((0, K)),
                     1.0 / max(float(T.var()), 1e-12), y_mean)
    scale = norms[usable]
    Gn = G[np.ix_(usable, usable)] / np.outer(scale, scale)
    Bn = BtT[usable] / scale[:, None]
    A, alpha, beta = _steps(est, Gn, Bn, float((T * T).sum()), N)
    Sigma, Mu = _posterior(Gn[np.ix_(A, A)], Bn[A], alpha, beta)
    order = np.argsort(usable[A])
    A, alpha, Sigma, Mu = A[order], alpha[order], Sigma[np.ix_(order, order)], Mu[order]
    s = scale[A]
    return _keep(est, usable[A], phi_mean, alpha, Sigma / np.outer(s, s), Mu / s[:, None],
                 beta, y_mean)


def _keep(est, kept, phi_mean, alpha, sigma, W, beta, y_mean):
    """Store est's learned state: W (R, K) weights of the raw kernels in scaled output units."""
    est.relevance_ = np.asarray(kept, np.int64)
    est.centres_ = est.candidates_[est.relevance_]
    est.phi_mean_ = phi_mean[est.relevance_]
    est.alpha_, est.beta_, est.sigma_ = alpha, float(beta), sigma
    est.coef_ = W * est.y_scale_
    est.intercept_ = y_mean - est.phi_mean_ @ est.coef_
    est.noise_ = est.y_scale_ ** 2 / est.beta_
    return est


def _steps(est, Gram, BtT, TtT: float, N: int):
    """Tipping & Faul's sequential steps on unit-norm statistics Gram (M, M), BtT (M, K).

    Sets est's n_iter_, converged_, log_marginal_likelihood_; returns (active (R,), alpha (R,),
    beta).
    """
    K = BtT.shape[1]
    beta = min(1.0 / est.noise if est.noise is not None else 10.0, _BETA_MAX)
    first = int(np.argmax((BtT ** 2).sum(1)))     # the kernel best aligned with the targets
    A = np.array([first])
    qsum0 = beta ** 2 * float((BtT[first] ** 2).sum())
    alpha = np.array([min(K * beta ** 2 / max(qsum0 - K * beta, 1e-12 * K * beta), _ALPHA_MAX)])
    st = _Stats(Gram[:, A], BtT, A, alpha, beta)
    converged, step = False, 0
    for step in range(1, int(est.max_iter) + 1):
        if step % _REFRESH == 0:
            if est.noise is None:
                beta = better_beta(Gram, BtT, TtT, N, A, alpha, beta)
            st = _Stats(Gram[:, A], BtT, A, alpha, beta)
        gain, new_alpha, delete = step_gains(st, A, alpha, K, est.min_gain)
        j = int(np.argmax(gain))
        if not gain[j] > est.tol:
            new_beta = (beta if est.noise is not None
                        else better_beta(Gram, BtT, TtT, N, A, alpha, beta))
            if abs(np.log(new_beta / beta)) > 1e-3:     # it moved: go on with the new noise
                beta = new_beta
                st = _Stats(Gram[:, A], BtT, A, alpha, beta)
                continue
            converged = True
            break
        A, alpha = _apply(st, Gram, A, alpha, j, new_alpha[j], bool(delete[j]))
    est.n_iter_, est.converged_ = step, converged
    est.log_marginal_likelihood_ = log_marginal_likelihood(
        Gram[np.ix_(A, A)], BtT[A], TtT, N, K, alpha, beta)
    return A, alpha, beta


def _apply(st, Gram, A, alpha, j: int, alpha_j: float, delete: bool):
    """One step on basis j: add it with precision alpha_j, re-estimate it, or delete it;
    st's factors follow by the rank-one formulas. Returns the new (A, alpha)."""
    pos = np.flatnonzero(A == j)
    if len(pos) == 0:
        st.add(j, Gram[:, j], Gram[:, A], alpha_j)
        return np.append(A, j), np.append(alpha, alpha_j)
    pos = int(pos[0])
    if delete:
        st.delete(pos, Gram[:, A])
        return np.delete(A, pos), np.delete(alpha, pos)
    st.reestimate(pos, Gram[:, A], alpha_j, alpha[pos])
    alpha = alpha.copy()
    alpha[pos] = alpha_j
    return A, alpha
