"""The most probable sequence of hypotheses (Viterbi): where the silhouette is ambiguous a
mixture's favourite hypothesis is often wrong, but the body moves little between frames
(Agarwal and Triggs 2005). Hypothesis j at frame t has evidence log_weight[t, j]; a move from
i to j costs continuity * |y_t^j - y_{t-1}^i|^2 / (2 s^2), s^2 the training motion's mean
squared step."""
from __future__ import annotations

import numpy as np

from .angles import wrap_deg


class HypothesisPathError(ValueError):
    """Inputs of the wrong shape or value."""


def most_probable_path(poses, log_weight, step_var: float, continuity: float = 1.0,
                       sequence_ids=None, angles_deg: bool = False) -> np.ndarray:
    """The chosen hypothesis (T,) int of each frame, maximising evidence + smoothness.
    poses (T, M, K): M hypotheses per frame; log_weight (T, M): their log evidence (-inf
    excludes one); step_var: s^2; continuity: the smoothness term's weight (0: each frame's
    best alone); sequence_ids (T,): the chain restarts where the label changes; angles_deg:
    the poses are degrees, their steps wrapped to (-180, 180]."""
    poses = np.asarray(poses, dtype=np.float64)
    log_weight = np.asarray(log_weight, dtype=np.float64)
    if poses.ndim != 3 or log_weight.shape != poses.shape[:2] or 0 in poses.shape[:2]:
        raise HypothesisPathError(f"poses must be (T, M, K) and log_weight (T, M), T, M >= 1, "
                                  f"got shapes {poses.shape} and {log_weight.shape}")
    if not np.isfinite(poses).all() or np.isnan(log_weight).any():
        raise HypothesisPathError("poses must be finite and log_weight not NaN (-inf excludes)")
    if not (np.isfinite(step_var) and step_var > 0):
        raise HypothesisPathError(f"step_var must be > 0, got {step_var}")
    if not (np.isfinite(continuity) and continuity >= 0):
        raise HypothesisPathError(f"continuity must be >= 0, got {continuity}")
    T = len(poses)
    same = np.ones(max(T - 1, 0), bool) if sequence_ids is None else continues(sequence_ids, T)
    scale = continuity / (2.0 * step_var)
    score = log_weight[0].copy()
    back = np.zeros(poses.shape[:2], dtype=np.int64)
    # A loop over frames (each step depends on the last), vectorised over the M x M moves.
    for t in range(1, T):
        if same[t - 1]:
            d2 = squared_steps(poses[t - 1], poses[t], angles_deg)  # (M previous, M current)
            total = score[:, None] - scale * d2
            back[t] = total.argmax(axis=0)
            score = total[back[t], np.arange(total.shape[1])] + log_weight[t]
        else:
            # A new sequence: the last one's chain is traced back from its best end.
            back[t] = score.argmax()
            score = log_weight[t].copy()
    path = np.empty(T, dtype=np.int64)
    path[-1] = int(score.argmax())
    for t in range(T - 1, 0, -1):
        path[t - 1] = back[t, path[t]]
    return path


def squared_steps(before, after, angles_deg: bool = False) -> np.ndarray:
    """|after_j - before_i|^2 for every pair: before (M, K), after (M', K) -> (M, M'); with
    angles_deg, each difference (degrees) wrapped to (-180, 180] first."""
    step = after[None, :, :] - before[:, None, :]
    if angles_deg:
        step = wrap_deg(step)
    return (step ** 2).sum(axis=2)


def continues(sequence_ids, n: int) -> np.ndarray:
    """(n - 1,) whether row t + 1 is in row t's sequence."""
    ids = np.asarray(sequence_ids)
    if ids.shape != (n,):
        raise HypothesisPathError(f"sequence_ids must have one label per row ({n}), "
                                  f"got shape {np.shape(sequence_ids)}")
    return ids[1:] == ids[:-1]
