"""Silhouette layout: the fraction of each cell of a grid x grid raster over the silhouette's
bounding box made square that it covers (independent of the person's size and position, scene
vertical kept). The global complement of the shape contexts' histogram, which does not keep
where on the body a context is (a knee bent forwards or backwards gives much the same bag of
contexts). Measured gains: docs/code_notes/model.md.
"""
from __future__ import annotations

import cv2
import numpy as np

from .edges import DegenerateSilhouetteError

MAX_GRID = 64


def silhouette_layout(mask: np.ndarray, grid: int) -> np.ndarray:
    """Coverage (grid * grid,) float64 in [0, 1], row-major from the top-left, of the
    silhouette mask (H, W) (nonzero = person) over its bounding box made square (the box
    centred); area averaging, so a cell is its fraction of person pixels. Raises
    DegenerateSilhouetteError for an empty mask."""
    if not 1 <= int(grid) <= MAX_GRID:
        raise ValueError(f"layout grid must be 1..{MAX_GRID}, got {grid}")
    m = np.asarray(mask)
    if m.ndim != 2:
        raise DegenerateSilhouetteError(f"a silhouette mask must be 2-D, got shape {m.shape}")
    if m.dtype != bool:
        m = m != 0
    # The bounding box of the nonzero pixels (a bool mask's bytes are 0/1: viewed, not copied).
    left0, top0, w, h = cv2.boundingRect(m.view(np.uint8))
    if w == 0:
        raise DegenerateSilhouetteError("the silhouette is empty")
    crop = m[top0:top0 + h, left0:left0 + w]
    side = max(h, w)
    square = np.zeros((side, side), np.float32)
    top, left = (side - h) // 2, (side - w) // 2
    square[top:top + h, left:left + w] = crop
    return cv2.resize(square, (int(grid), int(grid)),
                      interpolation=cv2.INTER_AREA).astype(np.float64).ravel()

