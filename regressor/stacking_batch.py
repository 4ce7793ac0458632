"""Stacking a whole sequence of descriptors at once (regressor.stacking's rule): for training,
evaluation and the tracker's proposals; ``track`` stacks frame by frame (FrameStacker).
"""
from __future__ import annotations

import numpy as np

from .stacking import StackingInputError, _check_whole


def sequence_starts_to_ids(starts, n: int) -> np.ndarray:
    """Sequence id per frame (n,) from the sorted first-row indices of each sequence (must
    start at 0)."""
    starts = np.asarray(starts, dtype=np.int64).ravel()
    if starts.size == 0 or starts[0] != 0 or np.any(np.diff(starts) <= 0) \
            or starts[-1] >= max(n, 1):
        raise StackingInputError(f"sequence_starts {starts.tolist()} must be increasing, start "
                                 f"at 0 and be < {n}")
    ids = np.zeros(n, np.int64)
    ids[starts[1:]] = 1
    return np.cumsum(ids)


def stack_frames(X, k: int, sequence_ids=None, sequence_starts=None, step: int = 1) -> np.ndarray:
    """Each frame stacked with its k-1 predecessors in its sequence, step frames apart: (N, k*D)
    from X (N, D) in time order. sequence_ids (N,): a new sequence starts where the label
    changes; or sequence_starts: each sequence's first row; neither: one sequence."""
    X = np.asarray(X, dtype=np.float64)
    k, step = _check_whole(k, "depth k"), _check_whole(step, "step")
    if X.ndim != 2:
        raise StackingInputError(f"X must be (N, D); got shape {X.shape}")
    N = X.shape[0]
    if sequence_ids is not None and sequence_starts is not None:
        raise StackingInputError("give sequence_ids or sequence_starts, not both")
    if sequence_starts is not None:
        ids = sequence_starts_to_ids(sequence_starts, N)
    elif sequence_ids is not None:
        ids = np.asarray(sequence_ids).ravel()
        if ids.shape != (N,):
            raise StackingInputError(f"sequence_ids has shape {np.shape(sequence_ids)}; "
                                     f"expected ({N},)")
    else:
        ids = np.zeros(N, np.int64)
    # first[t] = index of the first frame of t's sequence (a run of equal labels).
    new_run = np.ones(N, bool)
    new_run[1:] = ids[1:] != ids[:-1]
    first = np.maximum.accumulate(np.where(new_run, np.arange(N), 0))
    t = np.arange(N)[:, None] - step * np.arange(k)[None, :]   # (N, k) source frames
    src = np.maximum(t, first[:, None])
    return X[src].reshape(N, k * X.shape[1])
