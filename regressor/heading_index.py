"""Nearest neighbours among a sample of training rows (regressor.heading_index_training), in
the regressor's projected input space: each frame's novelty (HeadingIndex.novelty). limit_deg
stays in model files for compatibility (docs/tuning.md, "regressor/heading_index.py").
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .basis import nearest_columns

#: Queries per block in HeadingIndex._nearest (distances: block x R float32).
_QUERY_BLOCK = 256


@dataclass
class HeadingIndex:
    """inputs (R, P): training rows' regressor inputs (first P components); folded_deg (R,):
    their folded headings (degrees); k neighbours per query; limit_deg: unused."""

    inputs: np.ndarray
    folded_deg: np.ndarray
    k: int
    limit_deg: float = 45.0

    def __post_init__(self):
        self.inputs = np.ascontiguousarray(self.inputs, dtype=np.float32)
        self.folded_deg = np.asarray(self.folded_deg, dtype=np.float64)
        if self.inputs.ndim != 2 or len(self.inputs) < 1 or self.inputs.shape[1] < 1 \
                or self.folded_deg.shape != (len(self.inputs),):
            raise ValueError(f"a heading index needs inputs (R >= 1, P >= 1) and folded "
                             f"headings (R,), got {self.inputs.shape} and "
                             f"{self.folded_deg.shape}")
        if int(self.k) != self.k or self.k < 1 or not 0.0 < self.limit_deg <= 90.0:
            raise ValueError(f"a heading index needs an integer k >= 1 and limit_deg in "
                             f"(0, 90], got k = {self.k}, limit_deg = {self.limit_deg}")
        self.k = int(self.k)
        self._squared = (self.inputs.astype(np.float64) ** 2).sum(axis=1).astype(np.float32)
        self._typical: dict = {}

    @property
    def dims(self) -> int:
        """P, the input components the index compares."""
        return int(self.inputs.shape[1])

    def distance(self, X: np.ndarray) -> np.ndarray:
        """The mean Euclidean distance (N,) from each row of X (N, >= P) to its k nearest
        training rows, in the projected input's units."""
        return np.sqrt(self._nearest_d2(X)).mean(axis=1)

    def typical_distance(self, percentile: float = 99.0, sample: int = 2000) -> float:
        """The percentile of distance() over a seeded sample of at most ``sample`` of the
        index's own rows, each left out of its neighbours (cached); NaN with k or fewer rows."""
        key = (float(percentile), int(sample))
        if key not in self._typical:
            n = len(self.inputs)
            if n <= self.k:
                return float("nan")
            pick = _random_rows(n, sample, seed=0)
            index, d2 = self._nearest(self.inputs[pick], extra=1)
            # Each row left out: its own entry dropped (or the farthest, if a duplicate's)
            own = index == pick[:, None]
            own[~own.any(axis=1), -1] = True
            own &= np.cumsum(own, axis=1) == 1                     # one entry per row
            kept = np.sqrt(d2[~own].reshape(len(pick), self.k))
            self._typical[key] = float(np.percentile(kept.mean(axis=1), percentile))
        return self._typical[key]

    def remember_typical_distance(self, value: float) -> None:
        """Take a model file's ``value`` as the default :meth:`typical_distance` instead of
        computing it. ValueError unless positive, finite and within a factor 4 of the same
        percentile over 50 rows, so a tampered value cannot call every frame unfamiliar."""
        value = float(value)
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"a heading index's typical distance must be positive and finite, "
                             f"got {value}")
        rough = self.typical_distance(sample=50)
        if np.isfinite(rough) and not rough / 4 <= value <= rough * 4:
            raise ValueError(f"a heading index's typical distance {value:g} is implausible for "
                             f"its rows (about {rough:.3g})")
        self._typical[(99.0, 2000)] = value

    def novelty(self, X: np.ndarray) -> np.ndarray:
        """How unlike the training silhouettes each row of X (N, >= P) is, (N,): :meth:`distance`
        over the training rows' own 99th percentile (about 1 % of them are above 1; far above,
        the regressor extrapolates). NaN when the index has k or fewer rows."""
        return self.distance(X) / max(self.typical_distance(), 1e-12)

    def _nearest(self, X: np.ndarray, extra: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """(indices (N, k'), squared distances (N, k') ascending) of the k' = k + extra
        nearest training rows of each row of X (N, >= P), queried in blocks."""
        Q, k = self._query(X, extra)
        index, dist2 = np.empty((len(Q), k), dtype=np.int64), np.empty((len(Q), k))
        for start in range(0, len(Q), _QUERY_BLOCK):
            q = Q[start:start + _QUERY_BLOCK]
            nearest, near_d2 = nearest_columns(self._partial_d2(q), k)
            index[start:start + len(q)] = nearest
            dist2[start:start + len(q)] = self._with_query_norm(near_d2, q)
        return index, dist2

    def _nearest_d2(self, X: np.ndarray) -> np.ndarray:
        """_nearest(X)[1] (N, k), the same values, without the rows' indices (cheaper)."""
        Q, k = self._query(X, 0)
        dist2 = np.empty((len(Q), k))
        for start in range(0, len(Q), _QUERY_BLOCK):
            q = Q[start:start + _QUERY_BLOCK]
            d2 = self._partial_d2(q)
            near_d2 = (np.sort(np.partition(d2, k - 1, axis=1)[:, :k], axis=1)
                       if k < d2.shape[1] else np.sort(d2, axis=1))
            dist2[start:start + len(q)] = self._with_query_norm(near_d2, q)
        return dist2

    def _query(self, X: np.ndarray, extra: int) -> tuple[np.ndarray, int]:
        """X's first P columns as float32 (N, P), and k + extra (at most R); ValueError when
        X has fewer columns."""
        Q = np.asarray(X, dtype=np.float32)[:, :self.dims]
        if Q.shape[1] != self.dims:
            raise ValueError(f"the heading index compares {self.dims} input columns, got "
                             f"{Q.shape[1]}")
        return Q, min(self.k + extra, len(self.inputs))

    def _partial_d2(self, q: np.ndarray) -> np.ndarray:
        """|row|^2 - 2 q.row (n, R) float32 for queries q (n, P): squared distances less the
        query's own norm. Computed as (rows @ q')' : the same dot products as q @ rows', and
        a faster product for a few queries than with rows' transposed (strided) view."""
        d2 = np.ascontiguousarray((self.inputs @ q.T).T)
        d2 *= -2.0
        d2 += self._squared
        return d2

    @staticmethod
    def _with_query_norm(near_d2: np.ndarray, q: np.ndarray) -> np.ndarray:
        """The squared distances (n, k) float64 from partial ones (n, k) of queries q (n, P):
        the query's own norm added back; float32 rounding can leave tiny negatives."""
        return np.maximum(near_d2 + (q.astype(np.float64) ** 2).sum(axis=1)[:, None], 0.0)


def _random_rows(n: int, at_most: int, seed: int) -> np.ndarray:
    """Sorted indices of at most ``at_most`` of n rows, drawn at random (seeded); all n
    rows when there are no more."""
    if n <= at_most:
        return np.arange(n)
    return np.sort(np.random.default_rng(seed).choice(n, at_most, replace=False))
