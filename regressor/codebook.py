"""A k-means codebook of shape contexts and soft (Gaussian) vote histograms on it.

The codebook is plain arrays (centres (K, D) float64, sigma float) so a model file can store it.
Fitting is seeded k-means++ followed by Lloyd iterations, vectorized in numpy: the same contexts
and seed give identical centres.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .basis import squared_distances
from .errors import SilhouettePoseError


class CodebookError(SilhouettePoseError, ValueError):
    """A codebook's arrays, or the data given to fit or use one, are malformed."""


#: The Gaussian votes' width. Shape contexts sum to 1, so two lie at most sqrt(2) apart: widths
#: outside this range are damage (1e300 had overflowed its square, 1e-300 made every vote NaN).
SIGMA_RANGE = (1e-6, 1e3)


@dataclass(frozen=True, eq=False)
class Codebook:
    """k-means centres of shape contexts and the width of the Gaussian votes onto them.

    centres: (K, D) float64, D = n_radial * n_angular (60 by default).
    sigma: vote width, in the same units as the distance between contexts (> 0).
    """

    centres: np.ndarray
    sigma: float

    def __post_init__(self) -> None:
        centres = np.asarray(self.centres)
        if centres.ndim != 2 or centres.shape[0] < 1 or centres.shape[1] < 1:
            raise CodebookError(f"codebook centres must be (K, D) with K, D >= 1, got shape {centres.shape}")
        if not np.all(np.isfinite(centres)):
            raise CodebookError("codebook centres contain NaN or infinite values")
        low, high = SIGMA_RANGE
        if not (np.isfinite(self.sigma) and low <= self.sigma <= high):
            raise CodebookError(f"codebook sigma must be within {low:g}..{high:g}, got "
                                f"{self.sigma}")
        centres = np.array(centres, dtype=np.float64)  # a private copy, read-only: a codebook never changes
        centres.flags.writeable = False
        object.__setattr__(self, "centres", centres)
        object.__setattr__(self, "sigma", float(self.sigma))

    @property
    def n_centres(self) -> int:
        """K, the number of centres (= descriptor length)."""
        return self.centres.shape[0]

    def to_arrays(self, prefix: str = "codebook_") -> dict[str, np.ndarray]:
        """Plain arrays for an .npz: {prefix+'centres': (K, D) float64, prefix+'sigma': () float64}."""
        return {prefix + "centres": self.centres.copy(), prefix + "sigma": np.array(self.sigma)}

    @classmethod
    def from_arrays(cls, arrays, prefix: str = "codebook_") -> "Codebook":
        """Rebuild from a mapping made by to_arrays (e.g. an NpzFile); validates shapes and values."""
        missing = [prefix + k for k in ("centres", "sigma") if prefix + k not in arrays]
        if missing:
            raise CodebookError(f"codebook arrays missing: {', '.join(missing)}")
        sigma = np.asarray(arrays[prefix + "sigma"])
        if sigma.shape != () or not np.issubdtype(sigma.dtype, np.floating):
            raise CodebookError(f"{prefix}sigma must be a float scalar, got shape {sigma.shape} dtype {sigma.dtype}")
        return cls(np.asarray(arrays[prefix + "centres"], dtype=np.float64), float(sigma))


def _kmeans_plus_plus(x: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """k-means++ seeding: k rows of x (k, D), each drawn with probability ~ squared distance to
    the nearest centre drawn so far."""
    n = len(x)
    chosen = np.empty(k, dtype=np.int64)
    chosen[0] = rng.integers(n)
    nearest = squared_distances(x, x[chosen[:1]])[:, 0]
    for j in range(1, k):  # k steps, each vectorized over all points
        total = nearest.sum()
        chosen[j] = rng.choice(n, p=nearest / total) if total > 0 else rng.integers(n)
        nearest = np.minimum(nearest, squared_distances(x, x[chosen[j : j + 1]])[:, 0])
    return x[chosen].copy()


def kmeans(x: np.ndarray, k: int, seed: int, max_iter: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """Seeded k-means (k-means++ then Lloyd) on rows of x.

    x: (N, D) float, N >= k. seed: integer seed of numpy's default Generator.
    Returns (centres (k, D) float64, labels (N,) int64). An empty cluster is re-seeded with the
    point farthest from its centre, so all k centres are distinct data-supported points/means.
    Stops when no label changes, or after max_iter iterations.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2 or len(x) < k or k < 1:
        raise CodebookError(f"k-means needs (N, D) data with N >= k = {k}, got shape {x.shape}")
    rng = np.random.default_rng(seed)
    centres = _kmeans_plus_plus(x, k, rng)
    labels = np.full(len(x), -1, dtype=np.int64)
    for _ in range(max_iter):
        d2 = squared_distances(x, centres)
        new_labels = d2.argmin(axis=1)
        if np.array_equal(new_labels, labels):
            break
        labels = new_labels
        counts = np.bincount(labels, minlength=k)
        dims = x.shape[1]
        flat = (labels[:, None] * dims + np.arange(dims)).ravel()
        sums = np.bincount(flat, weights=x.ravel(), minlength=k * dims).reshape(k, dims)
        empty = np.flatnonzero(counts == 0)
        centres = sums / np.maximum(counts, 1)[:, None]
        if len(empty):
            far = np.argsort(-d2[np.arange(len(x)), labels], kind="stable")[: len(empty)]
            centres[empty] = x[far]
    return centres, labels


def fit_codebook(
    contexts: np.ndarray,
    n_centres: int = 100,
    seed: int = 0,
    max_samples: int = 20000,
    max_iter: int = 100,
) -> Codebook:
    """Fit a codebook to shape contexts pooled from many silhouettes.

    contexts: (M, D) float, one context per row (each row sums to 1).
    n_centres: K. seed: integer seed (subsampling and k-means++). max_samples: at most this many
        rows (drawn without replacement) are clustered, for speed.
    sigma is set to the root-mean-square distance from the clustered rows to their nearest centre,
    so votes fall off on the scale at which contexts actually scatter around the centres.
    Returns a Codebook with centres (K, D).
    """
    contexts = np.asarray(contexts, dtype=np.float64)
    if contexts.ndim != 2 or not np.all(np.isfinite(contexts)):
        raise CodebookError(f"contexts must be a finite (M, D) array, got shape {contexts.shape}")
    if len(contexts) < n_centres:
        raise CodebookError(f"need at least n_centres = {n_centres} contexts to fit a codebook, got {len(contexts)}")
    rng = np.random.default_rng(seed)
    if len(contexts) > max_samples:
        contexts = contexts[np.sort(rng.choice(len(contexts), size=max_samples, replace=False))]
    centres, labels = kmeans(contexts, n_centres, seed=int(rng.integers(2**31)), max_iter=max_iter)
    residual = ((contexts - centres[labels]) ** 2).sum(axis=1)
    sigma = float(np.sqrt(residual.mean()))
    if not sigma > 0:
        raise CodebookError("all contexts coincide with a centre; give more varied contexts or fewer centres")
    return Codebook(centres, sigma)


def soft_histogram(contexts: np.ndarray, codebook: Codebook, n_votes: int = 5, total: float = 100.0) -> np.ndarray:
    """Soft vector quantization of one silhouette's contexts onto the codebook.

    contexts: (N, D) float, one silhouette's shape contexts.
    Each context votes into its n_votes nearest centres with weights exp(-d^2 / (2 sigma^2)),
    normalized to 1 per context (computed relative to the nearest centre, so no underflow).
    Returns (K,) float64 histogram summing to total.
    """
    contexts = np.asarray(contexts, dtype=np.float64)
    k = codebook.n_centres
    if contexts.ndim != 2 or contexts.shape[1] != codebook.centres.shape[1] or len(contexts) == 0:
        raise CodebookError(
            f"contexts must be (N, {codebook.centres.shape[1]}) with N >= 1 to match the codebook, got {contexts.shape}"
        )
    n_votes = min(n_votes, k)
    # |x - c|^2 less the per-row constant |x|^2: ranks centres the same, and the weights below
    # only use differences to the row's nearest centre, in which |x|^2 cancels.
    centres = codebook.centres
    d2 = (centres * centres).sum(axis=1)[None, :] - 2.0 * (contexts @ centres.T)
    # The n_votes nearest by repeated argmin (a few vectorized passes): faster than
    # np.argpartition on (300, 100) rows, and exact, ties going to the lower centre index.
    rows = np.arange(len(d2))
    nearest = np.empty((len(d2), n_votes), dtype=np.intp)
    near_d2 = np.empty((len(d2), n_votes))
    for j in range(n_votes):
        nearest[:, j] = d2.argmin(axis=1)
        near_d2[:, j] = d2[rows, nearest[:, j]]
        d2[rows, nearest[:, j]] = np.inf
    weights = np.exp(-(near_d2 - near_d2[:, :1]) / (2.0 * codebook.sigma**2))
    weights /= weights.sum(axis=1, keepdims=True)
    hist = np.bincount(nearest.ravel(), weights=weights.ravel(), minlength=k)
    return hist * (total / hist.sum())
