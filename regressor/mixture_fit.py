"""The fits of regressor.mixture's estimators (k-means, the damped kernel experts, the softmax
gate, the mixture) and their targets, loaded only when fitting."""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.sparse

from .angles import wrap_deg
from .basis import gaussian_design, squared_distances, validate_X
from .basis_fit import default_width
from .mixture import DampedKernelRegressor, SoftmaxGate

EXPERT_KINDS = ("ridge", "rvm", "sparse_rvm")
GATE_KINDS = ("softmax", "neighbours")
COMBINE_KINDS = ("most_probable", "mean")


def regression_targets(pose: np.ndarray, centre_deg: np.ndarray) -> np.ndarray:
    """Targets (N, 55): heading (cos, sin) as is, angles as wrap(angle - centre) in degrees."""
    out = np.array(pose, dtype=np.float64, copy=True)
    out[:, 2:] = wrap_deg(out[:, 2:] - centre_deg)
    return out


def kmeans(X: np.ndarray, k: int, seed: int = 0, iterations: int = 25,
           sample: int = 20000) -> np.ndarray:
    """k-means centres (k, D) of rows X (N, D): k-means++ start (on at most 4,000 of them),
    Lloyd iterations on at most ``sample`` rows, deterministic in seed. Empty clusters are
    re-seeded at the row farthest from its centre."""
    X = np.asarray(X, dtype=np.float64)
    rng = np.random.default_rng(seed)
    if len(X) > sample:
        X = X[np.sort(rng.choice(len(X), sample, replace=False))]
    k = min(k, len(X))
    # k-means++ seeding on at most 4,000 rows, squared norms computed once.
    seed_rows = X if len(X) <= 4000 else X[np.sort(rng.choice(len(X), 4000, replace=False))]
    norms = (seed_rows * seed_rows).sum(axis=1)
    centres = np.empty((k, X.shape[1]))
    centres[0] = seed_rows[rng.integers(len(seed_rows))]
    d2 = np.maximum(norms - 2 * seed_rows @ centres[0] + centres[0] @ centres[0], 0)
    for j in range(1, k):
        p = d2 / d2.sum() if d2.sum() > 0 else None
        centres[j] = seed_rows[rng.choice(len(seed_rows), p=p)]
        d2 = np.minimum(d2, np.maximum(norms - 2 * seed_rows @ centres[j]
                                       + centres[j] @ centres[j], 0))
    for _ in range(iterations):
        D = squared_distances(X, centres)
        label = D.argmin(axis=1)
        counts = np.bincount(label, minlength=k)
        # Sums per cluster as a sparse product (np.add.at is ~50x slower at this size).
        new = np.asarray(scipy.sparse.csr_matrix(
            (np.ones(len(X)), (label, np.arange(len(X)))), shape=(k, len(X))) @ X)
        empty = counts == 0
        new[~empty] /= counts[~empty, None]
        if empty.any():
            far = np.argsort(-D[np.arange(len(X)), label])[:empty.sum()]
            new[empty] = X[far]
        if np.allclose(new, centres):
            centres = new
            break
        centres = new
    return centres


def fit_damped(est, X, Y, sample_weight=None):
    """Fit the DampedKernelRegressor est on X (N, D), Y (N, K) or (N,); returns est."""
    X = validate_X(X)
    Y = np.asarray(Y, dtype=np.float64)
    Y2 = Y[:, None] if Y.ndim == 1 else Y
    est.width_ = default_width(X, est.width_scale)
    est.centres_ = kmeans(X, est.n_centres, seed=est.seed, iterations=8, sample=10000)
    Phi = gaussian_design(X, est.centres_, est.width_)
    w = np.ones(len(X)) if sample_weight is None else np.asarray(sample_weight, float)
    sw = w / w.sum()
    mean_phi = sw @ Phi
    mean_y = sw @ Y2
    P = (Phi - mean_phi) * np.sqrt(w)[:, None]
    T = (Y2 - mean_y) * np.sqrt(w)[:, None]
    A = P.T @ P
    damping = est.lam * max(float(np.trace(A)) / len(A), 1e-12)
    A[np.diag_indices_from(A)] += damping
    est.coef_ = scipy.linalg.solve(A, P.T @ T, assume_a="pos")
    est.intercept_ = mean_y - mean_phi @ est.coef_
    if Y.ndim == 1:
        est.coef_, est.intercept_ = est.coef_[:, 0], est.intercept_[0]
    est.n_features_in_ = X.shape[1]
    return est


def fit_softmax_gate(est, X, labels, n_classes: int | None = None, sample_weight=None):
    """Fit the SoftmaxGate est on X (N, D) and class labels (N,) int; returns est."""
    X = validate_X(X)
    labels = np.asarray(labels, dtype=np.int64)
    C = int(labels.max()) + 1 if n_classes is None else int(n_classes)
    est.n_classes_ = C
    est.width_ = default_width(X, est.width_scale)
    est.centres_ = kmeans(X, est.n_centres, seed=est.seed, iterations=8, sample=10000)
    raw = gaussian_design(X, est.centres_, est.width_)
    est.feature_mean_ = raw.mean(axis=0)
    est.feature_std_ = raw.std(axis=0) + 1e-6
    F = np.hstack([(raw - est.feature_mean_) / est.feature_std_, np.ones((len(X), 1))])
    N, P = F.shape
    onehot = np.zeros((N, C))
    onehot[np.arange(N), labels] = 1.0
    w = np.ones(N) if sample_weight is None else np.asarray(sample_weight, float)
    w = w / w.sum()
    penal = np.ones((P, C))
    penal[-1] = 0.0

    def loss(flat):
        W = flat.reshape(P, C)
        Z = F @ W
        Z -= Z.max(axis=1, keepdims=True)
        logp = Z - np.log(np.exp(Z).sum(axis=1, keepdims=True))
        value = -(w * (onehot * logp).sum(axis=1)).sum() + 0.5 * est.l2 * (penal * W * W).sum()
        grad = F.T @ ((np.exp(logp) - onehot) * w[:, None]) + est.l2 * penal * W
        return value, grad.ravel()

    res = scipy.optimize.minimize(loss, np.zeros(P * C), jac=True, method="L-BFGS-B",
                                  options={"maxiter": est.max_iter})
    est.weights_ = res.x.reshape(P, C)
    est.n_features_in_ = X.shape[1]
    return est


def fit_mixture(est, X, Y, Z=None, log=None, workers: int = 1):
    """Fit the MixtureRegressor est (its fit's arguments); returns est."""
    if est.expert not in EXPERT_KINDS:
        raise ValueError(f"expert must be one of {EXPERT_KINDS}, got {est.expert!r}")
    if est.gate not in GATE_KINDS:
        raise ValueError(f"gate must be one of {GATE_KINDS}, got {est.gate!r}")
    if est.combine not in COMBINE_KINDS:
        raise ValueError(f"combine must be one of {COMBINE_KINDS}, got {est.combine!r}")
    X = validate_X(X)
    Y = np.asarray(Y, dtype=np.float64)
    Z = Y if Z is None else np.asarray(Z, dtype=np.float64)
    if len(Y) != len(X) or len(Z) != len(X):
        raise ValueError("X, Y and Z must have the same number of rows")
    E = max(1, int(est.n_experts))
    est.partition_centres_ = kmeans(Z, E, seed=est.seed)
    E = len(est.partition_centres_)
    D = squared_distances(Z, est.partition_centres_)
    labels = D.argmin(axis=1)
    own = D[np.arange(len(Z)), labels]
    members = []
    for e in range(E):
        member = (labels == e) | (np.sqrt(D[:, e]) <= (1.0 + est.overlap) * np.sqrt(own))
        idx = np.flatnonzero(member)
        if est.expert == "rvm" and len(idx) > est.rvm_rows:
            idx = idx[np.linspace(0, len(idx) - 1, est.rvm_rows).astype(int)]
        members.append(idx)

    def fit_one(e: int):
        expert = _new_expert(est, e).fit(X[members[e]], Y[members[e]])
        if log:
            kept = getattr(expert, "relevance_", None)
            log(f"  expert {e}: {int((labels == e).sum())} rows of its own, "
                f"{len(members[e])} fitted"
                + ("" if kept is None else f", {len(kept)} relevance vectors kept"))
        return expert

    if int(workers) > 1:         # numpy releases the GIL in its matrix work
        with ThreadPoolExecutor(int(workers)) as pool:
            est.experts_ = list(pool.map(fit_one, range(E)))
    else:
        est.experts_ = [fit_one(e) for e in range(E)]
    est.expert_rows_ = np.array([len(idx) for idx in members])
    if est.gate == "neighbours":
        from .neighbour_gate import NeighbourGate
        est.gate_ = NeighbourGate(est.gate_neighbours, prototypes=est.gate_prototypes,
                                  seed=est.seed).fit(X, labels, n_classes=E)
    else:
        est.gate_ = SoftmaxGate(est.gate_centres, est.gate_width_scale, est.gate_l2,
                                seed=est.seed).fit(X, labels, n_classes=E)
    est.n_features_in_ = X.shape[1]
    est.n_outputs_ = Y.shape[1] if Y.ndim == 2 else 1
    return est


def _new_expert(est, e: int):
    """Expert e's unfitted regressor, as the mixture est's ``expert`` names it."""
    if est.expert == "ridge":
        return DampedKernelRegressor(est.n_centres, est.width_scale, est.lam, seed=est.seed + e)
    if est.expert == "sparse_rvm":
        from .sparse_rvm import SparseRVMRegressor
        return SparseRVMRegressor(n_candidates=est.n_centres, width_scale=est.width_scale,
                                  seed=est.seed + e, **(est.expert_params or {}))
    from .rvm import RVMRegressor
    return RVMRegressor("gaussian", width_scale=est.width_scale)
