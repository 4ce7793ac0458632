"""A k-means codebook of shape contexts (plain arrays, so a model file can store it; fitted by
regressor.training.fit_codebook) and soft (Gaussian) vote histograms on it."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import SilhouettePoseError


class CodebookError(SilhouettePoseError, ValueError):
    """A codebook's arrays, or the data given to fit or use one, are malformed."""


#: The Gaussian votes' width. Shape contexts sum to 1, so two lie at most sqrt(2) apart: widths
#: outside this range are damage (1e300 had overflowed its square, 1e-300 made every vote NaN).
SIGMA_RANGE = (1e-6, 1e3)


@dataclass(frozen=True, eq=False)
class Codebook:
    """centres (K, D) float64 of shape contexts, D = n_radial * n_angular; sigma: the
    Gaussian votes' width (the distance between contexts' units); squared_norms (K,) |centre|^2
    (made once here, not a field)."""

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
        norms = (centres * centres).sum(axis=1)   # |c|^2 (K,), used by every vote
        norms.flags.writeable = False
        object.__setattr__(self, "squared_norms", norms)

    @property
    def n_centres(self) -> int:
        """K, the number of centres (= descriptor length)."""
        return self.centres.shape[0]

    @classmethod
    def from_arrays(cls, arrays, prefix: str = "codebook_") -> "Codebook":
        """Rebuild from a mapping made by regressor.model_writer.codebook_arrays (e.g. an
        NpzFile); validates shapes and values."""
        missing = [prefix + k for k in ("centres", "sigma") if prefix + k not in arrays]
        if missing:
            raise CodebookError(f"codebook arrays missing: {', '.join(missing)}")
        sigma = np.asarray(arrays[prefix + "sigma"])
        if sigma.shape != () or not np.issubdtype(sigma.dtype, np.floating):
            raise CodebookError(f"{prefix}sigma must be a float scalar, got shape {sigma.shape} dtype {sigma.dtype}")
        return cls(np.asarray(arrays[prefix + "centres"], dtype=np.float64), float(sigma))


def soft_histogram(contexts: np.ndarray, codebook: Codebook, n_votes: int = 5, total: float = 100.0) -> np.ndarray:
    """Histogram (K,) float64 summing to total of one silhouette's contexts (N, D): each votes
    into its n_votes nearest centres with weights exp(-d^2 / (2 sigma^2)), normalised to 1 per
    context (relative to the nearest centre, so no underflow)."""
    return soft_histograms([contexts], codebook, n_votes, total)[0]


def soft_histograms(contexts, codebook: Codebook, n_votes: int = 5, total: float = 100.0) -> np.ndarray:
    """soft_histogram of each of B silhouettes' contexts, B (N, D) arrays with the same N (e.g.
    a silhouette's and its mirror image's): (B, K) float64, the same values as B calls."""
    contexts = [np.asarray(c, dtype=np.float64) for c in contexts]
    k, width = codebook.centres.shape
    n = len(contexts[0]) if contexts else 0
    for c in contexts:
        if c.ndim != 2 or c.shape[1] != width or len(c) == 0 or len(c) != n:
            raise CodebookError(f"contexts must be (N, {width}) with N >= 1 to match the codebook "
                                f"(the same N for all), got {c.shape}")
    # |x - c|^2 less the per-row constant |x|^2: ranks centres the same, and the weights below
    # only use differences to the row's nearest centre, in which |x|^2 cancels.
    d2 = np.empty((len(contexts), n, k))
    for c, out in zip(contexts, d2):
        np.matmul(c, codebook.centres.T, out=out)
    d2 *= -2.0
    d2 += codebook.squared_norms
    nearest, weights = _nearest(d2.reshape(-1, k), min(n_votes, k))
    weights -= weights[:, :1].copy()          # exp(-(d2 - nearest d2) / (2 sigma^2)), in place
    np.negative(weights, out=weights)
    weights /= 2.0 * codebook.sigma**2
    np.exp(weights, out=weights)
    weights /= weights.sum(axis=1, keepdims=True)
    # Centre indices made keys per silhouette (b * K + centre), rows in order: the same sums.
    nearest.reshape(len(contexts), -1)[...] += np.arange(0, len(contexts) * k, k)[:, None]
    hist = np.bincount(nearest.ravel(), weights=weights.ravel(), minlength=len(contexts) * k)
    hist = hist.reshape(len(contexts), k)
    return hist * (total / hist.sum(axis=1, keepdims=True))


def _nearest(d2: np.ndarray, n_votes: int) -> tuple[np.ndarray, np.ndarray]:
    """The n_votes smallest of each row of d2 (M, K) float64 (overwritten): (column indices
    (M, n_votes) intp, values (M, n_votes)), ascending, ties going to the lower column. By
    repeated argmin (a few vectorized passes): faster than np.argpartition on (300, 100) rows."""
    flat = d2.ravel()
    row_starts = np.arange(0, d2.size, d2.shape[1])
    nearest = np.empty((len(d2), n_votes), dtype=np.intp)
    near_d2 = np.empty((len(d2), n_votes))
    for j in range(n_votes):
        at = d2.argmin(axis=1)
        nearest[:, j] = at
        at += row_starts
        near_d2[:, j] = flat[at]
        flat[at] = np.inf
    return nearest, near_d2
