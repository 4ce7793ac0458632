"""Gait measures of knee flexion: do the knees bend at the right time, alternate, and reach
their range? (issue 52, "Left and right legs kept apart").

A regressor that cannot tell which leg is which in profile can average the two leg
configurations: both knees then bend together, half as far. The measures separate that from
timing:

- **timing**: correlation of the mean of both knees' flexion with the truth's mean;
- **alternation**: correlation of (left - right) knee flexion with the truth's (1: the
  right leg bends when the true right leg does; -1: the legs are swapped throughout; about 0:
  averaged or swapping at random);
- **range**: the knees' own spread, the mean of the two knees' standard deviations over the
  truth's (1: full range; an average of the two legs' configurations gives about half);
- **lr_corr**: the correlation of our left knee with our right (walking: negative, the legs
  alternate; both knees bending together: positive), beside the truth's.

Knee flexion is in degrees (0 = straight), (T, 2) arrays with columns (left, right) as
sequences.measures.flexion_deg's first two. A series that does not vary correlates 0
(sequences.measures.correlation).
"""
from __future__ import annotations

import numpy as np

from .measures import MeasureError, correlation, flexion_deg


def knee_flexion(vectors, template=None) -> np.ndarray:
    """Knee flexion (T, 2) degrees (left, right) of pose vectors (T, 55), by forward
    kinematics on the CMU skeleton (sequences.measures.flexion_deg)."""
    return flexion_deg(vectors, template)[:, :2]


def _knees(knees, name: str, frames: int | None = None) -> np.ndarray:
    k = np.asarray(knees, dtype=np.float64)
    if k.ndim != 2 or k.shape[1] != 2 or len(k) < 2 or (frames is not None and len(k) != frames):
        want = f"({frames if frames is not None else 'T >= 2'}, 2)"
        raise MeasureError(f"{name}: knee flexion must have shape {want}, got {k.shape}")
    if not np.isfinite(k).all():
        raise MeasureError(f"{name}: NaN or infinity in the knee flexion")
    return k


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    return float(correlation(a[:, None], b[:, None])[0])


def gait_measures(estimate, truth) -> dict:
    """The module docstring's measures of knee flexion estimate (T, 2) against truth (T, 2),
    degrees, columns (left, right). Returns floats: timing, alternation, range, lr_corr and
    truth_lr_corr (JSON-ready). range is NaN where the truth's knees do not move."""
    tru = _knees(truth, "truth")
    est = _knees(estimate, "estimate", len(tru))
    true_sd = tru.std(axis=0).mean()
    return {"timing": _corr(est.mean(axis=1), tru.mean(axis=1)),
            "alternation": _corr(est[:, 0] - est[:, 1], tru[:, 0] - tru[:, 1]),
            "range": float(est.std(axis=0).mean() / true_sd) if true_sd > 0 else float("nan"),
            "lr_corr": _corr(est[:, 0], est[:, 1]),
            "truth_lr_corr": _corr(tru[:, 0], tru[:, 1])}


def best_of(candidates, truth) -> np.ndarray:
    """Per frame, the candidate nearest the truth: candidates (T, K, 2) knee flexion of K
    hypotheses, truth (T, 2); nearness is the summed absolute error of both knees. Returns
    (T, 2): what an oracle choosing among the hypotheses would output (does any hypothesis
    carry the right leg configuration?)."""
    c = np.asarray(candidates, dtype=np.float64)
    tru = _knees(truth, "truth")
    if c.ndim != 3 or c.shape[0] != len(tru) or c.shape[2] != 2 or c.shape[1] < 1:
        raise MeasureError(f"candidates must have shape ({len(tru)}, K, 2), got {c.shape}")
    pick = np.abs(c - tru[:, None]).sum(axis=2).argmin(axis=1)
    return c[np.arange(len(c)), pick]


def swapped(knees) -> np.ndarray:
    """Knee flexion (T, 2) with left and right exchanged: what a silhouette's other leg
    configuration (sequences.pose_vector.front_back_flip in profile) gives."""
    return np.asarray(knees, dtype=np.float64)[:, ::-1].copy()
