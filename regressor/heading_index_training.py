"""Building a heading index from training rows (regressor.heading_index): training only."""
from __future__ import annotations

import numpy as np

from .angles import wrap_deg
from .heading_index import HeadingIndex, _random_rows


def fold_heading_deg(heading_deg) -> np.ndarray:
    """Of each heading h (degrees) and its front/back partner 180 - h, the one in [-90, 90]
    (facing the camera's half); same shape."""
    h = wrap_deg(np.asarray(heading_deg, dtype=np.float64))
    return np.where(np.abs(h) <= 90.0, h, np.copysign(180.0, h) - h)


def build_heading_index(inputs: np.ndarray, heading_deg: np.ndarray, rows: int, dims: int,
                        k: int, limit_deg: float = 45.0, seed: int = 0) -> HeadingIndex:
    """An index of at most ``rows`` training rows drawn at random (seeded) from inputs (N, >=
    dims) with their headings (N,) degrees, comparing the first ``dims`` columns."""
    inputs = np.asarray(inputs)
    n = len(inputs)
    if n == 0 or dims < 1 or rows < 1:        # k and the limit: HeadingIndex checks them
        raise ValueError("a heading index needs rows and dims >= 1 and some training rows")
    pick = _random_rows(n, rows, seed)
    return HeadingIndex(inputs[pick, :dims], fold_heading_deg(np.asarray(heading_deg)[pick]), k,
                        limit_deg)
