"""Basis functions for pose regression, and the estimator plumbing the regressors share.

A regressor predicts ``y = phi(x) @ W + b`` (b an unpenalised offset) on the ``"linear"`` basis
``phi(x) = x`` or the ``"gaussian"`` one ``phi(x)_j = exp(-||x - c_j||^2 / width^2)``. The
estimators follow the scikit-learn contract without importing it (Parameters).
"""
from __future__ import annotations

import inspect
import weakref

import numpy as np

from .errors import SilhouettePoseError


class RegressorInputError(SilhouettePoseError, ValueError):
    """Bad input to a regressor (shape, dtype, non-finite values, unknown option)."""


class RegressorTypeError(RegressorInputError, TypeError):
    """Input that is not numbers at all (e.g. objects in X)."""


class NotFittedError(SilhouettePoseError, ValueError, AttributeError):
    """``predict`` (or a learned attribute) was used before ``fit``."""


class Parameters:
    """scikit-learn's parameter protocol by hand: the constructor's arguments are the
    parameters, stored under their own names; fit returns self; learned state ends in _."""

    def _check_fitted(self, attribute: str = "coef_") -> None:
        if not hasattr(self, attribute):
            raise NotFittedError(f"this {type(self).__name__} is not fitted yet; call fit first")

    @classmethod
    def _param_names(cls) -> list[str]:
        return [p for p in inspect.signature(cls.__init__).parameters if p != "self"]

    def get_params(self, deep: bool = True) -> dict:
        """Constructor parameters as a dict."""
        return {name: getattr(self, name) for name in self._param_names()}

    def set_params(self, **params):
        """Set constructor parameters by name; returns self."""
        valid = self._param_names()
        for name, value in params.items():
            if name not in valid:
                raise RegressorInputError(
                    f"{type(self).__name__} has no parameter {name!r}; valid: {valid}")
            setattr(self, name, value)
        return self

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"


def squared_distances(A: np.ndarray, B: np.ndarray, B_squares: np.ndarray | None = None
                      ) -> np.ndarray:
    """Squared Euclidean distances, (n, D) x (m, D) -> (n, m), clipped at 0 against round-off.
    B_squares: (B * B).sum(1) (m,) when the caller keeps it (centre_squares)."""
    b2 = (B * B).sum(1) if B_squares is None else B_squares
    d2 = (A * A).sum(1)[:, None] + b2[None, :] - 2.0 * (A @ B.T)
    return np.maximum(d2, 0.0)


#: centre_squares' values by estimator: (its centres array, their squares summed); kept out of
#: the estimators' own attributes (predict leaves them as they are, as scikit-learn asks).
_CENTRE_SQUARES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def centre_squares(owner: object, centres: np.ndarray) -> np.ndarray:
    """(centres * centres).sum(1) (M,) of a fitted basis's centres (M, D), kept for ``owner``
    (an estimator) while its centres are this very array: squared_distances' part that
    depends on the centres alone, otherwise recomputed on every prediction."""
    kept = _CENTRE_SQUARES.get(owner)
    if kept is None or kept[0] is not centres:
        kept = (centres, (centres * centres).sum(1))
        _CENTRE_SQUARES[owner] = kept
    return kept[1]


def nearest_columns(d2: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The k smallest entries of each row of d2 (n, N), nearest first (k <= N): their column
    indices (n, k) int and values (n, k). For a block of squared distances from n queries to
    N rows (regressor.heading_index, regressor.neighbour_gate.NeighbourGate)."""
    nearest = (np.argpartition(d2, k - 1, axis=1)[:, :k] if k < d2.shape[1]
               else np.broadcast_to(np.arange(k), (len(d2), k)))
    near_d2 = np.take_along_axis(d2, nearest, axis=1)
    order = np.argsort(near_d2, axis=1)
    return np.take_along_axis(nearest, order, axis=1), np.take_along_axis(near_d2, order, axis=1)


def gaussian_design(X: np.ndarray, centres: np.ndarray, width: float,
                    squares: np.ndarray | None = None) -> np.ndarray:
    """Gaussian kernel design matrix: (N, D), (M, D) -> (N, M), exp(-||x - c||^2 / width^2);
    squares: the centres' squares summed (M,) (centre_squares), else computed here."""
    return np.exp(-squared_distances(X, centres, squares) / (width * width))


def validate_X(X, n_features: int | None = None, name: str = "X", owner: str = "the model") -> np.ndarray:
    """Check X is a finite 2-D real array (N, D) (D = n_features if given); return it as float64.
    Messages include scikit-learn's standard phrases so its estimator checks recognise them."""
    if hasattr(X, "toarray") or hasattr(X, "tocsr"):
        raise TypeError(f"{name}: sparse input is not supported; pass a dense array (X.toarray())")
    try:
        arr = np.asarray(X)
    except Exception as exc:  # ragged lists etc.
        raise RegressorInputError(f"{name} is not an array: {exc}") from None
    if np.iscomplexobj(arr):
        raise RegressorInputError(f"{name}: Complex data not supported; pass real numbers")
    try:
        arr = arr.astype(np.float64, copy=False)
    except (TypeError, ValueError) as exc:
        raise RegressorTypeError(f"{name} has dtype {arr.dtype}, which is not numeric ({exc})") from None
    if arr.ndim != 2:
        raise RegressorInputError(f"{name} must be 2-D (n_samples, n_features); got shape {arr.shape}. "
                                  "Reshape your data: X.reshape(1, -1) for a single sample")
    if arr.shape[0] < 1:
        raise RegressorInputError(f"{name}: found array with 0 sample(s) (shape={arr.shape}) while a minimum of 1 is required.")
    if arr.shape[1] < 1:
        raise RegressorInputError(f"{name}: found array with 0 feature(s) (shape={arr.shape}) while a minimum of 1 is required.")
    if n_features is not None and arr.shape[1] != n_features:
        raise RegressorInputError(f"{name} has {arr.shape[1]} features, but {owner} is expecting {n_features} features as input")
    if not np.all(np.isfinite(arr)):
        raise RegressorInputError(f"{name} contains NaN or infinity")
    return arr
