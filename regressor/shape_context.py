"""Log-polar shape contexts of a point set (Belongie, Malik & Puzicha), orientation kept: each
point's histogram of the other points in n_angular sectors x n_radial log-spaced rings, summing
to 1. Conventions (fixed, so descriptors made anywhere agree):
- Angles counterclockwise from image +x with image "up" positive (the scene vertical is kept:
  a mirrored silhouette gives different contexts); sector k covers [k, k+1) * 360/n_angular deg.
- Distances in units of the RMS distance between all pairs of points (exact in O(N) from the
  points' variance; within about 10% of the mean pairwise distance for silhouettes). Rings are
  geometric from r_inner to r_outer; ring 0 also takes nearer points and the last farther ones.
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
    """Shape contexts (N, n_radial * n_angular) float64, rows summing to 1, of points (N, 2)
    float (x, y) px, y down, N >= 2 not all coincident; 0 < r_inner < r_outer (module docstring)."""
    points = np.asarray(points, dtype=np.float64)
    n = len(points)
    if points.ndim != 2 or points.shape[1] != 2 or n < 2:
        raise ValueError(f"points must be (N, 2) with N >= 2, got shape {points.shape}")
    if not 0.0 < r_inner < r_outer:
        raise ValueError(f"need 0 < r_inner < r_outer, got r_inner={r_inner}, r_outer={r_outer}")
    # float32 pairwise arrays on contiguous x / y planes: several times faster than float64 on
    # interleaved (N, N, 2) views, and exact enough for pixel coordinates (centred first).
    centred = points - points.mean(axis=0)
    # RMS pairwise distance, exactly, in O(N): mean over i != j of |p_i - p_j|^2 = 2 N/(N-1) var.
    scale = np.sqrt(2.0 * n / (n - 1) * (centred**2).sum(axis=1).mean())
    if not scale > 0.0:
        raise ValueError("points are all coincident; shape contexts are undefined")
    x, y = centred.astype(np.float32).T.copy()
    u = x[None, :] - x[:, None]  # u[i, j]: point j relative to point i, rightwards
    v = y[:, None] - y[None, :]  # v[i, j]: upwards (rows grow downwards)
    # Below, (N, N) work is done in place on float32 / int32 arrays: at N = 300 the cost is memory
    # traffic, not arithmetic.

    # Sector in a doubled range [n_angular/2, 3 n_angular/2] so a plain truncating cast floors it,
    # then the wrap-around (sectors >= n_angular) folded back: a histogram of n_angular sectors.
    angle = np.arctan2(v, u)
    angle *= np.float32(n_angular / (2 * np.pi))
    angle += np.float32(n_angular)
    sector = angle.astype(np.int32)
    np.subtract(sector, n_angular, out=sector, where=sector >= n_angular)

    # Ring k holds log distances in [k, k+1) steps above r_inner * scale (step = log ratio / n_radial).
    log_step = np.log(r_outer / r_inner) / n_radial
    ring = u
    ring *= u
    v *= v
    ring += v
    with np.errstate(divide="ignore"):  # log(0) on the diagonal; clipped and discarded below
        np.log(ring, out=ring)
    ring -= np.float32(2.0 * np.log(r_inner * scale))
    ring *= np.float32(0.5 / log_step)
    np.clip(ring, np.float32(0.0), np.float32(n_radial - 0.5), out=ring)

    size = n_radial * n_angular
    bins = ring.astype(np.int32)
    bins *= n_angular
    bins += sector
    bins.flat[:: n + 1] = size  # a point is not its own neighbour: send it to a spare column
    bins += np.arange(0, n * (size + 1), size + 1, dtype=np.int32)[:, None]
    counts = np.bincount(bins.ravel(), minlength=n * (size + 1)).reshape(n, size + 1)
    return counts[:, :size] / float(n - 1)


def mirrored_bins(n_angular: int = 12, n_radial: int = 5) -> np.ndarray:
    """Bin order that turns a shape context into the context of the mirror-image point set
    (x -> -x, the image flipped left to right): contexts_of_mirror = contexts[:, order].

    Mirroring sends an angle a to 180 - a, so sector k goes to sector n_angular/2 - 1 - k
    (mod n_angular); rings are unchanged. Exact for points off the sector boundaries. Needs an
    even n_angular (a sector edge at 90 degrees); ValueError otherwise. Returns
    (n_radial * n_angular,) int, a permutation (its own inverse)."""
    if n_angular < 2 or n_angular % 2:
        raise ValueError(f"mirrored contexts need an even number of sectors, got {n_angular}")
    sectors = (n_angular // 2 - 1 - np.arange(n_angular)) % n_angular
    return (np.arange(n_radial)[:, None] * n_angular + sectors[None, :]).ravel()
