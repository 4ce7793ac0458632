"""Edge points at equal arc length along a silhouette's largest outer contour (OpenCV) and
optionally its holes, in pixels (x = column, y = row pointing down)."""
from __future__ import annotations

import cv2
import numpy as np

from .errors import SilhouettePoseError

# A person's silhouette is never thinner than this (smaller / larger standard deviation of its
# edge points): a 1-pixel line scores below 0.02, a person standing arms down about 0.2.
MIN_THICKNESS_RATIO = 0.05
# Fewer boundary pixels than this cannot give a meaningful shape context histogram.
MIN_EDGE_PIXELS = 10
# Holes with a shorter boundary than this (pixels) are treated as segmentation noise.
MIN_HOLE_PERIMETER = 8.0


class SilhouetteError(SilhouettePoseError, ValueError):
    """The input is not a usable silhouette mask (wrong shape or type)."""


class DegenerateSilhouetteError(SilhouetteError):
    """The mask is valid but holds no usable silhouette (empty, a few pixels, or a line)."""


def as_mask(mask: np.ndarray) -> np.ndarray:
    """A silhouette mask (H, W) bool or integer (nonzero = person) as a contiguous (H, W) uint8
    array of 0/1; SilhouetteError for anything but a 2-D bool or integer array."""
    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise SilhouetteError(f"silhouette mask must be 2-D (H, W), got shape {mask.shape}")
    if mask.dtype == bool:       # already 0/1 bytes: a view, no pass over the pixels
        return np.ascontiguousarray(mask).view(np.uint8)
    if not np.issubdtype(mask.dtype, np.integer):
        raise SilhouetteError(f"silhouette mask must be bool or integer, got dtype {mask.dtype}")
    return np.ascontiguousarray(mask != 0, dtype=np.uint8)


def _boundaries(mask01: np.ndarray, include_holes: bool) -> list[np.ndarray]:
    """Closed boundary polylines (M_i, 2) float64 (x, y) px: the largest outer contour first,
    then (if asked) its holes. Raises DegenerateSilhouetteError when there is no silhouette."""
    if not mask01.any():
        raise DegenerateSilhouetteError("silhouette mask is empty (no foreground pixels)")
    # A 1-pixel zero border so that silhouettes touching the image edge still get closed contours.
    padded = cv2.copyMakeBorder(mask01, 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=0)
    mode = cv2.RETR_CCOMP if include_holes else cv2.RETR_EXTERNAL
    contours, hierarchy = cv2.findContours(padded, mode, cv2.CHAIN_APPROX_NONE)
    hierarchy = hierarchy.reshape(-1, 4)  # next, previous, first child, parent
    outer = [i for i in range(len(contours)) if hierarchy[i, 3] < 0]
    # Largest by enclosed area; ties (e.g. zero-area lines) broken by boundary length.
    best = max(outer, key=lambda i: (cv2.contourArea(contours[i]), len(contours[i])))
    polylines = [contours[best].reshape(-1, 2).astype(np.float64) - 1.0]
    if include_holes:
        holes = [i for i in range(len(contours)) if hierarchy[i, 3] == best]
        for i in holes:
            hole = contours[i].reshape(-1, 2).astype(np.float64) - 1.0
            if cv2.arcLength(contours[i], True) >= MIN_HOLE_PERIMETER:
                polylines.append(hole)
    return polylines


def _closed_lengths(polyline: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A closed polyline (M, 2) as (vertices (M+1, 2) with the first repeated at the end,
    cumulative arc length (M+1,) px starting at 0)."""
    closed = np.vstack([polyline, polyline[:1]])
    step = closed[1:] - closed[:-1]
    cum = np.empty(len(closed))
    cum[0] = 0.0
    np.cumsum(np.hypot(step[:, 0], step[:, 1]), out=cum[1:])
    return closed, cum


def _resample_closed(closed: np.ndarray, cum: np.ndarray, count: int) -> np.ndarray:
    """count points (count, 2) at equal arc length along a closed polyline, from its start.
    closed, cum: as returned by _closed_lengths."""
    targets = np.arange(count) * (cum[-1] / count)
    return np.column_stack([np.interp(targets, cum, closed[:, 0]), np.interp(targets, cum, closed[:, 1])])


def _thickness_ratio(points: np.ndarray) -> float:
    """sqrt(smaller / larger eigenvalue) of the (2, 2) covariance of points (N, 2): 0 for a line."""
    cxx, cyy = points.var(axis=0)
    cxy = ((points[:, 0] - points[:, 0].mean()) * (points[:, 1] - points[:, 1].mean())).mean()
    half_sum, root = 0.5 * (cxx + cyy), np.hypot(0.5 * (cxx - cyy), cxy)
    return float(np.sqrt(max(half_sum - root, 0.0) / (half_sum + root))) if half_sum > 0 else 0.0


def _split_count(lengths: np.ndarray, total: int) -> np.ndarray:
    """Share total points among boundaries in proportion to their lengths (largest remainder)."""
    if len(lengths) == 1:
        return np.array([total])
    share = total * lengths / lengths.sum()
    counts = np.floor(share).astype(int)
    order = np.argsort(-(share - counts), kind="stable")
    counts[order[: total - counts.sum()]] += 1
    return counts


def sample_edge_points(mask: np.ndarray, n_points: int = 300, include_holes: bool = False) -> np.ndarray:
    """n_points (n_points, 2) float64 (x, y) px at equal arc length along the boundary of mask
    (H, W) bool/integer (nonzero = person); with include_holes shared among the outer boundary
    and its holes in proportion to their lengths. Raises DegenerateSilhouetteError for an
    empty mask, fewer than MIN_EDGE_PIXELS boundary pixels, or a line (MIN_THICKNESS_RATIO).
    """
    if n_points < MIN_EDGE_PIXELS:
        raise ValueError(f"n_points must be at least {MIN_EDGE_PIXELS}, got {n_points}")
    polylines = _boundaries(as_mask(mask), include_holes)
    if len(polylines[0]) < MIN_EDGE_PIXELS:
        raise DegenerateSilhouetteError(
            f"silhouette boundary has {len(polylines[0])} pixels, fewer than {MIN_EDGE_PIXELS}"
        )
    traced = [_closed_lengths(p) for p in polylines]
    counts = _split_count(np.array([cum[-1] for _, cum in traced]), n_points)
    points = np.vstack([_resample_closed(closed, cum, c) for (closed, cum), c in zip(traced, counts) if c > 0])
    ratio = _thickness_ratio(points)
    if ratio < MIN_THICKNESS_RATIO:
        raise DegenerateSilhouetteError(f"silhouette is a line (thickness ratio {ratio:.3f} < {MIN_THICKNESS_RATIO})")
    return points
