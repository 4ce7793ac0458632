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

import functools

import numpy as np


def _differences(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(u, v) as one (2, N, N) float32 array, u[j, i] = x[j] - x[i] (point j rightwards of
    point i) and v[j, i] = y[i] - y[j] (upwards), from x, y (N,) float32. One sgemm of the rows
    [x_j, 1, 0, 0], [0, 0, -y_j, 1] by the columns [1, -x_i, 1, y_i]: exactly the subtractions
    (each element is one rounded sum of exact products and zeros), in a third of their time;
    a -0.0 coordinate (whose difference keeps a sign the sgemm would lose) takes the plain
    subtractions."""
    n = len(x)
    if np.signbit(x[x == 0]).any() or np.signbit(y[y == 0]).any():
        uv = np.empty((2, n, n), np.float32)
        np.subtract(x[:, None], x[None, :], out=uv[0])
        np.subtract(y[None, :], y[:, None], out=uv[1])
        return uv
    left = np.zeros((2 * n, 4), np.float32)
    left[:n, 0] = x
    left[:n, 1] = 1.0
    left[n:, 2] = -y
    left[n:, 3] = 1.0
    right = np.ones((4, n), np.float32)
    right[1] = -x
    right[3] = y
    return (left @ right).reshape(2, n, n)


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
    # float32 pair arrays (centred first: exact enough for pixel coordinates), much faster
    centred = points - points.mean(axis=0)
    # RMS pairwise distance, exactly, in O(N): mean over i != j of |p_i - p_j|^2 = 2 N/(N-1) var.
    squares = centred * centred
    scale = np.sqrt(2.0 * n / (n - 1) * (squares[:, 0] + squares[:, 1]).mean())
    if not scale > 0.0:
        raise ValueError("points are all coincident; shape contexts are undefined")
    x, y = centred.T.astype(np.float32, order="C")
    # Pairs [j, i] (j seen from i): np.bincount counts such keys faster. In place throughout:
    # at N = 300 the cost is memory traffic, not arithmetic.
    uv = _differences(x, y)

    # Sector in a doubled range [n_angular/2, 3 n_angular/2] so a plain truncating cast floors it,
    # then the wrap-around (sectors >= n_angular) folded back: min(s, s - n_angular) in unsigned
    # integers, where s - n_angular wraps above s when s < n_angular.
    size = n_radial * n_angular
    key_type = np.uint16 if n * size <= np.iinfo(np.uint16).max else np.uint32
    angle = np.arctan2(uv[1], uv[0])
    angle *= np.float32(n_angular / (2 * np.pi))
    angle += np.float32(n_angular)
    sector = angle.astype(key_type)
    np.minimum(sector, sector - key_type(n_angular), out=sector)

    # Ring k holds log distances in [k, k+1) steps above r_inner * scale (step = log ratio / n_radial).
    log_step = np.log(r_outer / r_inner) / n_radial
    uv *= uv
    ring = uv[0]
    ring += uv[1]
    with np.errstate(divide="ignore"):  # log(0) on the diagonal: ring 0 after the clip
        np.log(ring, out=ring)
    ring -= np.float32(2.0 * np.log(r_inner * scale))
    ring *= np.float32(0.5 / log_step)
    np.clip(ring, np.float32(0.0), np.float32(n_radial - 0.5), out=ring)
    return _count_bins(ring.astype(key_type), sector, n_angular, size)


def _count_bins(ring: np.ndarray, sector: np.ndarray, n_angular: int, size: int) -> np.ndarray:
    """Each point's histogram (N, n_radial * n_angular) float64 of the other points, from ring
    and sector (N, N) unsigned integers (overwritten), both [j, i] (point j seen from point i):
    key i * size + ring * n_angular + sector. A point counts itself once, always in bin 0
    (distance 0: ring 0; arctan2(+0, +0) = 0: sector 0), taken off after counting. Keys of the
    smallest unsigned type that holds them (uint16 at 300 points: less memory traffic)."""
    n = len(ring)
    bins = ring
    bins *= n_angular
    bins += sector
    bins += np.arange(0, n * size, size, dtype=bins.dtype)
    counts = np.bincount(bins.ravel(), minlength=n * size).reshape(n, size)
    counts[:, 0] -= 1
    return counts / float(n - 1)


def mirrored_bins(n_angular: int = 12, n_radial: int = 5) -> np.ndarray:
    """Bin order (n_radial * n_angular,) int (read-only, its own inverse) that gives the
    contexts of the mirror-image point set (x -> -x): contexts[:, order]. An angle a goes to
    180 - a, so sector k to n_angular/2 - 1 - k (mod n_angular); rings stay. Exact off the
    sector boundaries; ValueError unless n_angular is even (a sector edge at 90 degrees)."""
    if n_angular < 2 or n_angular % 2:
        raise ValueError(f"mirrored contexts need an even number of sectors, got {n_angular}")
    return _mirrored_bins(int(n_angular), int(n_radial))


@functools.lru_cache(maxsize=8)
def _mirrored_bins(n_angular: int, n_radial: int) -> np.ndarray:
    sectors = (n_angular // 2 - 1 - np.arange(n_angular)) % n_angular
    order = (np.arange(n_radial)[:, None] * n_angular + sectors[None, :]).ravel()
    order.flags.writeable = False
    return order
