"""Stacked past-frame descriptors: the regressor input at frame t is [x_t, x_{t-s}, ...,
x_{t-(k-1)s}] (stack_step picks s); frames before a sequence's start repeat its first frame.
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


def stack_step(video_fps: float, model_fps: float) -> int:
    """Frames between stacked descriptors so that a video at video_fps stacks frames about as
    far apart in time as training at model_fps did (frames/s): the nearest whole ratio, >= 1."""
    if not (np.isfinite(video_fps) and video_fps > 0 and np.isfinite(model_fps) and model_fps > 0):
        raise StackingInputError(f"frame rates must be positive, got video {video_fps}, "
                                 f"model {model_fps}")
    return max(1, int(np.floor(video_fps / model_fps + 0.5)))


class FrameStacker:
    """Streaming stacking for one track, as regressor.stacking_batch.stack_frames: holds its
    last (k - 1) * step + 1 descriptors; the first push pads with its own descriptor."""

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
            self._buffer[1:] = self._buffer[:-1]    # in place (numpy copies overlapping rows safely)
            self._buffer[0] = x
        return self._buffer[::self.step].flatten()    # a copy: the buffer changes


def __getattr__(name: str):
    """Whole sequences' stacking (regressor.stacking_batch), loaded on first use."""
    if name in ("stack_frames", "sequence_starts_to_ids"):
        from . import stacking_batch
        return getattr(stacking_batch, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
