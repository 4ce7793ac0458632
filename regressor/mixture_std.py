"""regressor.mixture.MixtureRegressor.predict, with the standard deviations sparse RVM experts
give (offline evaluation and variance calibration; ``track`` asks only for hypotheses)."""
from __future__ import annotations

import numpy as np


def predict_mixture(est, X, return_std: bool = False):
    """est's (a fitted MixtureRegressor) poses (N, K) per row: the most probable expert's, or
    with combine="mean" the gate's weighting of all the experts' poses. return_std: also the
    standard deviation (N, K) of a new observation, the expert's or the mixture's (its second
    moment less the squared mean), for experts that give one (expert="sparse_rvm"). (N,) for
    a single output."""
    m = 1 if est.combine == "most_probable" else len(est.experts_)
    if return_std:
        poses, prob, stds = hypotheses_with_std(est, X, m)
    else:
        poses, prob = est.predict_hypotheses(X, m)
    prob = prob[:, :, None]
    mean = (poses * prob).sum(axis=1)
    if not return_std:
        return mean if est.n_outputs_ > 1 else mean[:, 0]
    std = np.sqrt(np.maximum((prob * (stds ** 2 + poses ** 2)).sum(axis=1) - mean ** 2, 0.0))
    return (mean, std) if est.n_outputs_ > 1 else (mean[:, 0], std[:, 0])


def hypotheses_with_std(est, X, m: int | None = None):
    """est.predict_hypotheses(X, m) and each pose's predictive standard deviation (N, m, K):
    (poses, probabilities, stds); ValueError unless the experts give one (sparse RVMs)."""
    X, order, prob = est._top_experts(X, m, None)
    if est.expert != "sparse_rvm":
        raise ValueError(f"return_std needs experts with a predictive variance "
                         f"(expert='sparse_rvm'), not expert={est.expert!r}")
    poses = np.empty((len(X), order.shape[1], est.n_outputs_))
    stds = np.empty_like(poses)
    for e in np.unique(order):
        rows, slot = np.nonzero(order == e)
        mean, std = est.experts_[e].predict(X[rows], return_std=True)
        stds[rows, slot] = np.asarray(std).reshape(len(rows), -1)
        poses[rows, slot] = np.asarray(mean).reshape(len(rows), -1)
    return poses, prob, stds
