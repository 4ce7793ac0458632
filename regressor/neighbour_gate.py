"""NeighbourGate: a mixture's gate by the nearest training inputs (or k-means prototypes of
them), the paper's alternative to the softmax gate; regressor.mixture_fit imports it only for
MixtureRegressor(gate="neighbours").
"""
from __future__ import annotations

import numpy as np

from .basis import Parameters, nearest_columns, squared_distances, validate_X
from .mixture_fit import kmeans


class NeighbourGate(Parameters):
    """p(class | x) from the classes of x's k nearest training inputs (Euclidean).

    The share of the k neighbours in class c is Bayes' rule with k-nearest-neighbour density
    estimates p(x | c) and the class frequencies as the prior: the gate as a density per
    expert in descriptor space (Agarwal and Triggs 2005), estimated without a parametric form.
    It keeps every training input, so it suits small sets (the paper's 1,927 frames), not the
    tracker's model file; with ``prototypes`` P it keeps P k-means centres of the inputs
    instead, each voting with the class counts of the rows nearest it (a compact gate: its
    basis is P points, not N rows). Ties between classes go to the class of the nearer
    neighbours (each vote is weighted 1 + 1e-6 x (k - rank)). Learned: X_ (N or P, D),
    counts_ (N or P, C) the classes each stored point votes for."""

    def __init__(self, n_neighbours: int = 3, chunk_rows: int = 2048,
                 prototypes: int | None = None, seed: int = 0):
        self.n_neighbours = n_neighbours
        self.chunk_rows = chunk_rows
        self.prototypes = prototypes
        self.seed = seed

    def fit(self, X, labels, n_classes: int | None = None):
        """X (N, D) training inputs, labels (N,) int classes 0..C-1; n_classes C (default:
        the largest label + 1)."""
        X = validate_X(X)
        labels = np.asarray(labels, dtype=np.int64)
        if len(labels) != len(X):
            raise ValueError("X and labels must have the same number of rows")
        self.n_classes_ = int(labels.max()) + 1 if n_classes is None else int(n_classes)
        if self.prototypes is None:
            self.X_, owner = X, np.arange(len(X))
        else:
            if not 1 <= int(self.prototypes) <= len(X):
                raise ValueError(f"prototypes must be within 1..{len(X)} (the training rows), "
                                 f"got {self.prototypes}")
            self.X_ = kmeans(X, int(self.prototypes), seed=self.seed)
            owner = squared_distances(X, self.X_).argmin(axis=1)
        counts = np.zeros((len(self.X_), self.n_classes_))
        np.add.at(counts, (owner, labels), 1.0)
        keep = counts.sum(axis=1) > 0               # a centre no row is nearest to votes for none
        self.X_, self.counts_ = self.X_[keep], counts[keep]
        if not 1 <= int(self.n_neighbours) <= len(self.X_):
            raise ValueError(f"n_neighbours must be within 1..{len(self.X_)} (the points kept), "
                             f"got {self.n_neighbours}")
        self.n_features_in_ = X.shape[1]
        return self

    def predict_proba(self, X) -> np.ndarray:
        """p(class | x), (N, C), rows summing to 1."""
        self._check_fitted("counts_")
        X = validate_X(X, self.n_features_in_)
        k = int(self.n_neighbours)
        votes = 1.0 + 1e-6 * np.arange(k, 0, -1)         # ties: the nearer neighbours' class
        P = np.zeros((len(X), self.n_classes_))
        for start in range(0, len(X), self.chunk_rows):  # bounded memory: chunk x N distances
            D = squared_distances(X[start:start + self.chunk_rows], self.X_)
            near, _ = nearest_columns(D, k)
            P[start:start + len(D)] = np.einsum("nk,nkc->nc", np.broadcast_to(votes, near.shape),
                                                self.counts_[near])
        return P / P.sum(axis=1, keepdims=True)

    def predict(self, X) -> np.ndarray:
        """Most probable class (N,)."""
        return self.predict_proba(X).argmax(axis=1)
