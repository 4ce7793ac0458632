"""A mixture of kernel regression experts with a gate (after Agarwal and Triggs, "Monocular
human motion capture with a mixture of regressors", CVPR Workshops 2005): an expert per region
of pose space (fitted with a margin of rows near its border, so neighbours agree where they
meet) and a gate p(expert | stacked descriptor). Where a silhouette is ambiguous (front/back)
two experts get similar probabilities: predict_hypotheses returns both poses. Per frame, only
the top experts' kernels run. Why these experts, where the fits are: docs/code_notes/regress.md.
"""
from __future__ import annotations

import numpy as np

from .basis import Parameters, centre_squares, gaussian_design, validate_X


class DampedKernelRegressor(Parameters):
    """Gaussian-kernel ridge regression on n_centres k-means centres of the inputs.

    width_scale: kernel width^2 = width_scale x mean squared distance between inputs
    (regressor.basis_fit.default_width); lam: damping, relative to the mean diagonal of
    Phi^T Phi / N; the offset is not damped. Learned: centres_ (M, D), width_, coef_ (M, K),
    intercept_ (K,)."""

    def __init__(self, n_centres: int = 500, width_scale: float = 0.25, lam: float = 0.01,
                 seed: int = 0):
        self.n_centres = n_centres
        self.width_scale = width_scale
        self.lam = lam
        self.seed = seed

    def fit(self, X, Y, sample_weight=None):
        """Fit on X (N, D), Y (N, K) or (N,) (regressor.mixture_fit); returns self."""
        from .mixture_fit import fit_damped
        return fit_damped(self, X, Y, sample_weight)

    def predict(self, X):
        self._check_fitted("coef_")
        X = validate_X(X, self.n_features_in_)
        Phi = gaussian_design(X, self.centres_, self.width_, centre_squares(self, self.centres_))
        return Phi @ self.coef_ + self.intercept_


class SoftmaxGate(Parameters):
    """Multinomial logistic regression p(class | x) on Gaussian-kernel features of x.

    Features: exp(-||x - c||^2 / width^2) on n_centres k-means centres of the inputs (width as
    regressor.basis_fit.default_width with width_scale), standardised, plus a constant. l2: ridge
    penalty on the weights (per row of data, not on the constant). Fitted by L-BFGS on the mean
    cross-entropy. Learned: centres_, width_, feature_mean_, feature_std_, weights_ (F+1, C)."""

    def __init__(self, n_centres: int = 300, width_scale: float = 0.5, l2: float = 1e-4,
                 max_iter: int = 300, seed: int = 0):
        self.n_centres = n_centres
        self.width_scale = width_scale
        self.l2 = l2
        self.max_iter = max_iter
        self.seed = seed

    def fit(self, X, labels, n_classes: int | None = None, sample_weight=None):
        """Fit on X (N, D) and class labels (N,) int (regressor.mixture_fit); returns self."""
        from .mixture_fit import fit_softmax_gate
        return fit_softmax_gate(self, X, labels, n_classes, sample_weight)

    def predict_proba(self, X) -> np.ndarray:
        """p(class | x), (N, C), rows summing to 1."""
        self._check_fitted("weights_")
        X = validate_X(X, self.n_features_in_)
        F = (gaussian_design(X, self.centres_, self.width_, centre_squares(self, self.centres_))
             - self.feature_mean_)
        Z = np.hstack([F / self.feature_std_, np.ones((len(F), 1))]) @ self.weights_
        Z -= Z.max(axis=1, keepdims=True)
        P = np.exp(Z)
        return P / P.sum(axis=1, keepdims=True)

    def predict(self, X) -> np.ndarray:
        """Most probable class (N,)."""
        return self.predict_proba(X).argmax(axis=1)


class MixtureRegressor(Parameters):
    """Mixture of kernel regression experts with a gate (module docstring).

    n_experts: regions of pose space (k-means on fit's Z, else on Y). overlap: an expert also
    trains on rows within (1 + overlap) x their distance to their own region's centre (0: hard
    partition). expert: "ridge" (DampedKernelRegressor: n_centres, width_scale, lam), "rvm"
    (regressor.rvm.RVMRegressor on at most rvm_rows rows per expert) or "sparse_rvm"
    (regressor.sparse_rvm on all its rows: n_centres candidates, width_scale, expert_params).
    gate: "softmax" (SoftmaxGate: gate_centres, gate_width_scale, gate_l2) or "neighbours"
    (NeighbourGate over gate_neighbours training inputs, or gate_prototypes k-means centres of
    them). top_experts: experts evaluated per row (their poses are the hypotheses). combine:
    predict's pose, "most_probable" or "mean" (weighted by the gate: smoother where it
    hesitates, but an average of the hypotheses). Learned: partition_centres_ (E, dZ),
    experts_, gate_, expert_rows_ (E,) rows each expert was fitted on.
    """

    def __init__(self, n_experts: int = 8, overlap: float = 0.2, expert: str = "ridge",
                 n_centres: int = 500, width_scale: float = 0.25, lam: float = 0.01,
                 gate_centres: int = 300, gate_width_scale: float = 0.5, gate_l2: float = 1e-4,
                 top_experts: int = 2, rvm_rows: int = 2000, seed: int = 0,
                 gate: str = "softmax", gate_neighbours: int = 3,
                 gate_prototypes: int | None = None, expert_params: dict | None = None,
                 combine: str = "most_probable"):
        self.n_experts = n_experts
        self.overlap = overlap
        self.expert = expert
        self.n_centres = n_centres
        self.width_scale = width_scale
        self.lam = lam
        self.gate_centres = gate_centres
        self.gate_width_scale = gate_width_scale
        self.gate_l2 = gate_l2
        self.top_experts = top_experts
        self.rvm_rows = rvm_rows
        self.seed = seed
        self.gate = gate
        self.gate_neighbours = gate_neighbours
        self.gate_prototypes = gate_prototypes
        self.expert_params = expert_params
        self.combine = combine

    def fit(self, X, Y, Z=None, log=None, workers: int = 1):
        """X (N, D) inputs, Y (N, K) targets, Z (N, dZ) the space partitioned (default Y).
        log(str) reports progress. workers: experts fitted at once (threads; the experts do
        not depend on it). Returns self (regressor.mixture_fit)."""
        from .mixture_fit import fit_mixture
        return fit_mixture(self, X, Y, Z, log, workers)

    def predict_proba(self, X) -> np.ndarray:
        """The gate: p(expert | x), (N, E)."""
        self._check_fitted("gate_")
        return self.gate_.predict_proba(X)

    def predict_hypotheses(self, X, m: int | None = None, proba: np.ndarray | None = None):
        """The m most probable experts' poses for each row: (poses (N, m, K), probabilities
        (N, m), most probable first; probabilities are the gate's, renormalised over the m).
        proba: the gate's predict_proba(X) (N, E) when the caller has it already."""
        X, order, prob = self._top_experts(X, m, proba)
        poses = np.empty((len(X), order.shape[1], self.n_outputs_))
        for e in np.unique(order):
            rows, slot = np.nonzero(order == e)
            mean = self.experts_[e].predict(X[rows])
            poses[rows, slot] = np.asarray(mean).reshape(len(rows), -1)
        return poses, prob

    def _top_experts(self, X, m: int | None, proba: np.ndarray | None):
        """(X (N, D) as floats, the m most probable experts (N, m) int, most probable first,
        their probabilities renormalised over the m (N, m)) for predict_hypotheses."""
        self._check_fitted("gate_")
        X = validate_X(X, self.n_features_in_)
        m = min(self.top_experts if m is None else int(m), len(self.experts_))
        P = self.gate_.predict_proba(X) if proba is None else proba
        order = np.argsort(-P, axis=1, kind="stable")[:, :m]
        prob = np.take_along_axis(P, order, axis=1)
        return X, order, prob / np.maximum(prob.sum(axis=1, keepdims=True), 1e-300)

    def predict(self, X, return_std: bool = False):
        """(N, K) per row: the most probable expert's pose, or with combine="mean" the gate's
        weighting of all the experts' poses; (N,) for a single output. return_std: also the
        standard deviation of a new observation (regressor.mixture_std; sparse RVM experts)."""
        from .mixture_std import predict_mixture
        return predict_mixture(self, X, return_std)
