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
