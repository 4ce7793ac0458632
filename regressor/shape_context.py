"""Log-polar shape contexts of a point set (Belongie, Malik & Puzicha), orientation kept.

Each point's context is the histogram of the other points' positions relative to it, in
n_angular equal angle sectors x n_radial log-spaced distance rings, normalized to sum to 1.

Conventions (fixed, so descriptors made anywhere agree):
- Angles are measured counterclockwise from the image +x axis with image "up" (decreasing row)
  positive, i.e. the scene vertical is kept: an upside-down or mirrored silhouette gives
  different contexts. Sector k covers [k, k+1) * 360/n_angular degrees.
- Distances are in units of the mean distance between all pairs of points (scale invariance).
  Ring boundaries are geometrically spaced from r_inner to r_outer (in those units); ring 0 also
  takes points closer than r_inner and the last ring points farther than r_outer, so every other
  point is counted once and each context sums to exactly 1.
- Bin index = ring * n_angular + sector.
"""
from __future__ import annotations

import numpy as np


def shape_contexts(
    points: np.ndarray,
    n_angular: int = 12,
    n_radial: int = 5,
    r_inner: float = 0.125,
    r_outer: float = 3.0,
) -> np.ndarray:
    """Shape context of every point of a set.

    points: (N, 2) float (x, y) pixels, y pointing down; N >= 2, not all coincident.
    n_angular, n_radial: numbers of angle sectors and distance rings.
    r_inner, r_outer: innermost and outermost ring boundaries, in units of the mean pairwise
        distance (0 < r_inner < r_outer).
    Returns (N, n_radial * n_angular) float64, each row summing to 1.
    """
    points = np.asarray(points, dtype=np.float64)
    n = len(points)
    if points.ndim != 2 or points.shape[1] != 2 or n < 2:
        raise ValueError(f"points must be (N, 2) with N >= 2, got shape {points.shape}")
    if not 0.0 < r_inner < r_outer:
        raise ValueError(f"need 0 < r_inner < r_outer, got r_inner={r_inner}, r_outer={r_outer}")
    # float32 pairwise arrays on contiguous x / y planes: several times faster than float64 on
    # interleaved (N, N, 2) views, and exact enough for pixel coordinates (centred first).
    centred = (points - points.mean(axis=0)).astype(np.float32)
    x, y = centred[:, 0], centred[:, 1]
    u = x[None, :] - x[:, None]  # u[i, j]: point j relative to point i, rightwards
    v = y[:, None] - y[None, :]  # v[i, j]: upwards (rows grow downwards)
    dist = np.sqrt(u * u + v * v)
    scale = dist.sum(dtype=np.float64) / (n * (n - 1))
    if not scale > 0.0:
        raise ValueError("points are all coincident; shape contexts are undefined")

    sector = np.floor(np.arctan2(v, u) * np.float32(n_angular / (2 * np.pi)) + np.float32(n_angular))
    sector = sector.astype(np.int32) % n_angular
    log_step = np.log(r_outer / r_inner) / n_radial
    with np.errstate(divide="ignore"):  # log(0) on the diagonal; clipped and discarded below
        ring = (np.log(dist) - np.float32(np.log(r_inner * scale))) * np.float32(1.0 / log_step)
    ring = np.clip(np.floor(ring), 0, n_radial - 1).astype(np.int32)

    n_bins = n_radial * n_angular
    bins = ring * n_angular + sector
    bins.flat[:: n + 1] = n_bins  # a point is not its own neighbour: send it to a spare column
    flat = bins + (np.arange(n, dtype=np.int32) * (n_bins + 1))[:, None]
    counts = np.bincount(flat.ravel(), minlength=n * (n_bins + 1)).reshape(n, n_bins + 1)
    return counts[:, :n_bins] / float(n - 1)
