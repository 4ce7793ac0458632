"""Relevance vector machine with a columnwise (shared) prior, fitted by fast marginal likelihood.

Model, for K outputs at once (Tipping 2001, with the paper's columnwise prior):
    T = B W + E,   B (N, M) basis (centred, unit-norm columns),  W (M, K),  E ~ N(0, 1/beta)
    row i of W ~ N(0, I_K / alpha_i): ONE precision per basis function, shared by all outputs,
so a basis function (a descriptor feature, or a training example) is kept or dropped for all
outputs together. Outputs are standardised (zero mean, unit variance) first so that one noise
level beta serves all of them; the offset is handled by centring (an unpenalised intercept).

Fitting is Tipping & Faul's (2003) sequential fast marginal likelihood, generalised to shared
alpha: with the usual per-output sparsity / quality factors s_i, q_ik, the log marginal
likelihood as a function of alpha_i is
    l(alpha_i) = 1/2 [ K log(alpha_i / (alpha_i + s_i)) + Qsum_i / (alpha_i + s_i) ],
    Qsum_i = sum_k q_ik^2,
maximised at alpha_i = K s_i^2 / (Qsum_i - K s_i) when Qsum_i > K s_i, else at infinity
(basis pruned). Each iteration takes the single add / re-estimate / delete step with the
largest likelihood gain, so only the active basis (R << N) is ever inverted: O(N R^2) per step,
starting from one basis function. This is fast and robust at a few thousand examples.

Sparsity: under plain ML-II an irrelevant basis survives whenever Qsum_i > K s_i, which for pure
noise (Qsum_i / s_i ~ chi^2_K) happens with probability ~0.3-0.45. ``min_gain`` charges a fixed
number of nats per kept basis (maximising L - min_gain * R, an L0-like cost in the spirit of
the paper's L0-ish prior): additions must gain more than it, and a basis whose contribution
l(alpha_i) falls below it is deleted. 0.5 * K * log(N) is a BIC-like choice.

``noise`` fixes 1/beta (a fraction of each output's variance) or, when None, beta is re-estimated
every few steps from the residual and the effective number of parameters.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg

from .basis import RegressorInputError
from .basis_regressor import BasisRegressor

_ALPHA_MAX = 1e12      # precisions above this count as "pruned"
_BETA_MAX = 1e6        # noise variance floor 1e-6 of the output variance (avoids interpolation)
_REFRESH = 50          # steps between exact recomputations (and noise re-estimates when noise=None)


def _log_gain(alpha: np.ndarray, s: np.ndarray, qsum: np.ndarray, K: int) -> np.ndarray:
    """l(alpha) above: the log marginal likelihood contributed by bases with precision alpha."""
    with np.errstate(divide="ignore", invalid="ignore"):   # s <= 0 only from round-off: no gain
        out = 0.5 * (K * np.log(alpha / (alpha + s)) + qsum / (alpha + s))
    return np.where(np.isfinite(out), out, -np.inf)


class _Posterior:
    """Posterior over the active weights: Sigma (R, R), Mu (R, K), from alpha (R,), beta."""

    def __init__(self, G_AA: np.ndarray, BtT_A: np.ndarray, alpha: np.ndarray, beta: float):
        H = beta * G_AA
        H[np.diag_indices_from(H)] += alpha
        try:
            chol = scipy.linalg.cho_factor(H, lower=True, check_finite=False)
        except np.linalg.LinAlgError:
            H[np.diag_indices_from(H)] += 1e-10 * np.trace(H)
            chol = scipy.linalg.cho_factor(H, lower=True, check_finite=False)
        self.Sigma = scipy.linalg.cho_solve(chol, np.eye(len(alpha)), check_finite=False)
        self.Mu = beta * (self.Sigma @ BtT_A)


class _Stats:
    """Posterior (Sigma (R, R), Mu (R, K)) and the factors S (M,), Q (M, K) for every basis.

    S_m = beta - beta^2 g_m Sigma g_m^T and Q_m = beta (B^T T)_m - beta g_m Mu with g_m row m of
    G = B^T B_A (M, R). The update methods are Tipping & Faul's (2003, appendix) rank-one
    formulas; Mu and Q carry K columns because the outputs share alpha and beta.
    """

    def __init__(self, G: np.ndarray, BtT: np.ndarray, A: np.ndarray, alpha: np.ndarray, beta: float):
        post = _Posterior(G[A].copy(), BtT[A], alpha, beta)
        self.beta = beta
        self.Sigma, self.Mu = post.Sigma, post.Mu
        self.S = beta - beta ** 2 * ((G @ self.Sigma) * G).sum(1)
        self.Q = beta * BtT - beta * (G @ self.Mu)

    def reestimate(self, pos: int, G: np.ndarray, alpha_new: float, alpha_old: float) -> None:
        Sj, mu_j = self.Sigma[:, pos].copy(), self.Mu[pos].copy()
        kappa = 1.0 / (Sj[pos] + 1.0 / (alpha_new - alpha_old))
        e = self.beta * (G @ Sj)
        self.Sigma -= kappa * np.outer(Sj, Sj)
        self.Mu -= kappa * np.outer(Sj, mu_j)
        self.S += kappa * e * e
        self.Q += kappa * np.outer(e, mu_j)

    def add(self, j: int, g_new: np.ndarray, G: np.ndarray, alpha_j: float) -> None:
        b = self.beta
        s_ii = 1.0 / (alpha_j + self.S[j])
        mu_i = s_ii * self.Q[j]
        c = b * (self.Sigma @ G[j])                       # beta Sigma B_A^T b_j  (R,)
        e = b * g_new - b * (G @ c)                       # beta B^T (b_j - beta B_A Sigma B_A^T b_j)
        R = len(c)
        Sigma = np.empty((R + 1, R + 1))
        Sigma[:R, :R] = self.Sigma + s_ii * np.outer(c, c)
        Sigma[:R, R] = Sigma[R, :R] = -s_ii * c
        Sigma[R, R] = s_ii
        self.Sigma = Sigma
        self.Mu = np.vstack([self.Mu - np.outer(c, mu_i), mu_i])
        self.S -= s_ii * e * e
        self.Q -= np.outer(e, mu_i)

    def delete(self, pos: int, G: np.ndarray) -> None:
        Sj, mu_j = self.Sigma[:, pos].copy(), self.Mu[pos].copy()
        s_jj = Sj[pos]
        e = self.beta * (G @ Sj)
        self.S += e * e / s_jj
        self.Q += np.outer(e, mu_j) / s_jj
        Sigma = self.Sigma - np.outer(Sj, Sj) / s_jj
        Mu = self.Mu - np.outer(Sj, mu_j) / s_jj
        self.Sigma = np.delete(np.delete(Sigma, pos, 0), pos, 1)
        self.Mu = np.delete(Mu, pos, 0)


def step_gains(st: "_Stats", A: np.ndarray, alpha: np.ndarray, K: int, min_gain: float):
    """Each basis function's best step and what it gains (Tipping & Faul 2003, shared alpha).

    st: the current factors S (M,), Q (M, K); A (R,) active indices, alpha (R,) their
    precisions. An inactive basis may be added, an active one re-estimated or deleted; the gain
    is in nats of L - min_gain * R (adding costs min_gain, deleting refunds it). Deleting the
    last active basis is never offered. Returns (gain (M,), -inf where no step pays; the new
    alpha (M,), inf where the basis should be out; delete (M,) bool, the step is a deletion).
    """
    M = len(st.S)
    s, q = st.S.copy(), st.Q.copy()
    denom = alpha - st.S[A]
    s[A] = alpha * st.S[A] / denom
    q[A] = (alpha / denom)[:, None] * st.Q[A]
    qsum = (q * q).sum(1)
    theta = qsum - K * s

    in_model = np.zeros(M, bool)
    in_model[A] = True
    good = (theta > 0) & (s > 0)
    new_alpha = np.full(M, np.inf)
    new_alpha[good] = np.minimum(K * s[good] ** 2 / theta[good], _ALPHA_MAX)
    gain = np.full(M, -np.inf)
    add = good & ~in_model
    gain[add] = 0.5 * ((qsum[add] / s[add] - K) - K * np.log(qsum[add] / (K * s[add])))
    gain[add] -= min_gain
    old = _log_gain(alpha, s[A], qsum[A], K)
    re_gain = np.full(len(A), -np.inf)
    re = good[A]
    re_gain[re] = _log_gain(new_alpha[A[re]], s[A[re]], qsum[A[re]], K) - old[re]
    del_gain = min_gain - old if len(A) > 1 else np.full(len(A), -np.inf)
    deleting = del_gain >= re_gain
    gain[A] = np.where(deleting, del_gain, re_gain)
    delete = np.zeros(M, bool)
    delete[A[deleting]] = True
    return gain, new_alpha, delete


def check_learning_options(est) -> None:
    """Refuse (RegressorInputError, naming the option) the sparse Bayesian learning options
    both RVMs share: output_scale, noise, min_gain, max_iter, tol."""
    if est.output_scale not in ("each", "common"):
        raise RegressorInputError(f"output_scale={est.output_scale!r}; expected 'each' or 'common'")
    if est.noise is not None and not (np.isfinite(est.noise) and est.noise > 0):
        raise RegressorInputError(f"noise={est.noise!r}; expected a positive number or None")
    if not (np.isfinite(est.min_gain) and est.min_gain >= 0):
        raise RegressorInputError(f"min_gain={est.min_gain!r}; expected a number >= 0")
    if not (int(est.max_iter) == est.max_iter and est.max_iter >= 1):
        raise RegressorInputError(f"max_iter={est.max_iter!r}; expected a positive integer")
    if not (np.isfinite(est.tol) and est.tol > 0):
        raise RegressorInputError(f"tol={est.tol!r}; expected a positive number")


class RVMRegressor(BasisRegressor):
    """Multi-output relevance vector regression with one relevance set for all outputs.

    Parameters
    ----------
    basis : "gaussian" (selects training examples) or "linear" (selects descriptor features).
    noise : noise variance as a fraction of the output variance (0 < noise), or None to
        estimate it. Larger -> fewer relevance vectors and smoother fits.
    output_scale : "each" standardises every output to unit variance (for mixed units, e.g.
        angles and cos/sin); "common" divides all outputs by one scale (the RMS of their standard
        deviations) so outputs keep their relative weights, matching a Euclidean error on points.
    width, width_scale : Gaussian kernel width (regressor.basis_fit.default_width); ignored for
        the linear basis.
    min_gain : cost in nats per kept basis function (maximise L - min_gain * R); 0 is the plain
        RVM, larger values give sparser models. 0.5 * K * log(N) is BIC-like.
    max_iter : maximum add / re-estimate / delete steps.
    tol : stop when no step raises the (cost-adjusted) log marginal likelihood by more than tol nats.

    Learned: relevance_ (R,) kept basis indices, coef_ (R, K), intercept_ (K,), alpha_ (R,)
    prior precisions (on unit-norm, centred columns, standardised outputs), noise_ (K,) noise
    variance per output in output units, centres_ (R, D) for the Gaussian basis, width_,
    n_iter_, converged_ (bool), n_features_in_.
    """

    def __init__(self, basis: str = "gaussian", noise: float | None = None, width: float | None = None,
                 width_scale: float = 1.0, output_scale: str = "each", min_gain: float = 0.0,
                 max_iter: int = 5000, tol: float = 0.1):
        self.basis = basis
        self.noise = noise
        self.width = width
        self.width_scale = width_scale
        self.output_scale = output_scale
        self.min_gain = min_gain
        self.max_iter = max_iter
        self.tol = tol

    def _check_options(self) -> None:
        check_learning_options(self)

    def _fit_weights(self, Phi: np.ndarray, Y: np.ndarray):
        self._check_options()
        N, K = Y.shape
        y_mean, y_std = Y.mean(0), Y.std(0)
        if self.output_scale == "common":   # one scale: outputs keep their relative weights
            y_std = np.full(K, np.sqrt(np.mean(y_std ** 2)))
        y_std = np.where(y_std > 0, y_std, 1.0)
        T = (Y - y_mean) / y_std

        phi_mean = Phi.mean(0)
        B = Phi - phi_mean
        norms = np.sqrt((B * B).sum(0))
        usable = np.flatnonzero(norms > 1e-12 * max(norms.max(initial=0.0), 1e-300))
        if len(usable) == 0:  # every basis column is constant: only the offset can be fitted
            self.alpha_, self.noise_, self.n_iter_, self.converged_ = np.zeros(0), Y.var(0), 0, True
            return np.zeros(0, np.int64), np.zeros((0, K)), Y.mean(0)
        B = B[:, usable] / norms[usable]

        active, alpha, beta, n_iter, converged = self._marginal_likelihood_steps(B, T)
        G_AA = B[:, active].T @ B[:, active]
        post = _Posterior(G_AA, B[:, active].T @ T, alpha, beta)

        kept = usable[active]
        order = np.argsort(kept)
        kept, alpha, Mu = kept[order], alpha[order], post.Mu[order]
        W = Mu / norms[kept][:, None] * y_std
        self.alpha_ = alpha
        self.noise_ = y_std ** 2 / beta
        self.n_iter_ = n_iter
        self.converged_ = converged
        return kept, W, y_mean - phi_mean[kept] @ W

    def _marginal_likelihood_steps(self, B: np.ndarray, T: np.ndarray):
        """Sequential fast marginal likelihood on unit-norm B (N, M) and scaled T (N, K).

        Sigma, Mu, S, Q are updated by Tipping & Faul's rank-one formulas (O(M R) per step) and
        recomputed from scratch every ``_REFRESH`` steps and after each noise re-estimate.
        Returns (active indices (R,), alpha (R,), beta, steps taken, converged).
        """
        N, K = T.shape
        BtT = B.T @ T                                     # (M, K)
        beta = min(1.0 / self.noise if self.noise is not None else 10.0, _BETA_MAX)

        # Start from the single basis function best aligned with the targets.
        first = int(np.argmax((BtT ** 2).sum(1)))
        A = np.array([first])
        G = (B.T @ B[:, first])[:, None]                  # (M, R): columns of B^T B_A
        qsum0 = beta ** 2 * float((BtT[first] ** 2).sum())
        alpha = np.array([K * beta ** 2 / max(qsum0 - K * beta, 1e-12 * K * beta)])
        st = _Stats(G, BtT, A, alpha, beta)

        converged = False
        step = 0
        for step in range(1, int(self.max_iter) + 1):
            if step % _REFRESH == 0:
                if self.noise is None:
                    beta = self._reestimate_beta(B, T, BtT, A, alpha, beta)
                st = _Stats(G, BtT, A, alpha, beta)
            gain, new_alpha, delete_set = step_gains(st, A, alpha, K, self.min_gain)

            j = int(np.argmax(gain))
            if not gain[j] > self.tol:
                if self.noise is None:   # converged for this beta: re-estimate it, go on if it moved
                    new_beta = self._reestimate_beta(B, T, BtT, A, alpha, beta)
                    if abs(np.log(new_beta / beta)) > 1e-3:
                        beta = new_beta
                        st = _Stats(G, BtT, A, alpha, beta)
                        continue
                converged = True
                break
            if not np.isin(j, A):
                g_new = B.T @ B[:, j]
                st.add(j, g_new, G, new_alpha[j])
                G = np.column_stack([G, g_new])
                A, alpha = np.append(A, j), np.append(alpha, new_alpha[j])
            else:
                pos = int(np.flatnonzero(A == j)[0])
                if not delete_set[j]:
                    st.reestimate(pos, G, new_alpha[j], alpha[pos])
                    alpha[pos] = new_alpha[j]
                else:
                    st.delete(pos, G)
                    G = np.delete(G, pos, axis=1)
                    A, alpha = np.delete(A, pos), np.delete(alpha, pos)
        return A, alpha, beta, step, converged

    @staticmethod
    def _reestimate_beta(B, T, BtT, active, alpha, beta) -> float:
        """Noise precision from the residual and the effective number of well-determined weights."""
        N, K = T.shape
        A = np.asarray(active)
        post = _Posterior(B[:, A].T @ B[:, A], BtT[A], np.asarray(alpha), beta)
        resid = T - B[:, A] @ post.Mu
        gamma = 1.0 - np.asarray(alpha) * np.diag(post.Sigma)
        dof = max(N - float(gamma.sum()), 1e-6)
        return float(min(K * dof / max(float((resid * resid).sum()), 1e-300), _BETA_MAX))
