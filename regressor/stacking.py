"""Stacked past-frame descriptors: the regressor input at frame t is [x_t, x_{t-s}, ...,
x_{t-(k-1)s}], step s = 1 at the training frame rate (:func:`stack_step` picks it for a faster
video). Frames before a sequence's start repeat its first frame, so nothing leaks across a
sequence boundary. k = 1 is the paper's per-frame regressor.
"""
from __future__ import annotations

import numpy as np

from .errors import SilhouettePoseError


class StackingInputError(SilhouettePoseError, ValueError):
    """Bad descriptors, sequence labels or depth given to stacking."""


def _check_whole(value, name: str) -> int:
    if not (int(value) == value and value >= 1):
        raise StackingInputError(f"stacking {name}={value!r}; expected an integer >= 1")
    return int(value)


def sequence_starts_to_ids(starts, n: int) -> np.ndarray:
    """Sequence id per frame (n,) from the sorted first-row indices of each sequence (must start at 0)."""
    starts = np.asarray(starts, dtype=np.int64).ravel()
    if starts.size == 0 or starts[0] != 0 or np.any(np.diff(starts) <= 0) or starts[-1] >= max(n, 1):
        raise StackingInputError(f"sequence_starts {starts.tolist()} must be increasing, start at 0 and be < {n}")
    ids = np.zeros(n, np.int64)
    ids[starts[1:]] = 1
    return np.cumsum(ids)


def stack_step(video_fps: float, model_fps: float) -> int:
    """Frames between stacked descriptors so that a video at video_fps stacks frames about as
    far apart in time as training at model_fps did (frames/s): the nearest whole ratio, >= 1."""
    if not (np.isfinite(video_fps) and video_fps > 0 and np.isfinite(model_fps) and model_fps > 0):
        raise StackingInputError(f"frame rates must be positive, got video {video_fps}, "
                                 f"model {model_fps}")
    return max(1, int(np.floor(video_fps / model_fps + 0.5)))


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
            raise StackingInputError(f"sequence_ids has shape {np.shape(sequence_ids)}; expected ({N},)")
    else:
        ids = np.zeros(N, np.int64)
    # first[t] = index of the first frame of t's sequence (a run of equal labels).
    new_run = np.ones(N, bool)
    new_run[1:] = ids[1:] != ids[:-1]
    first = np.maximum.accumulate(np.where(new_run, np.arange(N), 0))
    t = np.arange(N)[:, None] - step * np.arange(k)[None, :]   # (N, k) source frames
    src = np.maximum(t, first[:, None])
    return X[src].reshape(N, k * X.shape[1])


class FrameStacker:
    """Streaming stacking for one track, as stack_frames: holds its last (k - 1) * step + 1
    descriptors; the first push pads with its own descriptor."""

    def __init__(self, k: int, step: int = 1):
        self.k, self.step = _check_whole(k, "depth k"), _check_whole(step, "step")
        self._buffer: np.ndarray | None = None   # ((k - 1) * step + 1, D), newest first

    def push(self, x) -> np.ndarray:
        """Add descriptor x (D,) and return the stacked vector (k*D,)."""
        x = np.asarray(x, dtype=np.float64)
        if x.ndim != 1:
            raise StackingInputError(f"push expects one descriptor (D,); got shape {x.shape}")
        if self._buffer is None:
            self._buffer = np.repeat(x[None, :], (self.k - 1) * self.step + 1, axis=0)
        elif self._buffer.shape[1] != x.shape[0]:
            raise StackingInputError(f"descriptor has {x.shape[0]} values; this track's have {self._buffer.shape[1]}")
        else:
            self._buffer = np.vstack([x[None, :], self._buffer[:-1]])
        return self._buffer[::self.step].reshape(-1).copy()
