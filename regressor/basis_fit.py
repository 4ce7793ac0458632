"""The fit shared by the BasisRegressor subclasses (regressor.basis_regressor), and their
training data's validation; loaded only when fitting."""
from __future__ import annotations

import numpy as np

from .basis import RegressorInputError, gaussian_design, validate_X

BASIS_KINDS = ("linear", "gaussian")


def default_width(X: np.ndarray, width_scale: float = 1.0) -> float:
    """Kernel width from the data's scatter: sqrt(width_scale * mean ||x_i - x_j||^2).

    X: (N, D) training inputs. mean ||x_i - x_j||^2 over all pairs equals 2 * total variance,
    computed exactly in O(N D) (no pairwise matrix). Returns a positive float (units of X).
    """
    mean_sq = 2.0 * float(np.var(X, axis=0).sum())
    if not mean_sq > 0.0:
        raise RegressorInputError("cannot set a kernel width: all training inputs are identical")
    return float(np.sqrt(width_scale * mean_sq))


def validate_Xy(X, y) -> tuple[np.ndarray, np.ndarray, bool]:
    """Validate training data: X (N, D), y (N,) or (N, K). Returns (X, Y as (N, K), y_was_1d)."""
    X = validate_X(X)
    if y is None:
        raise RegressorInputError("this regressor requires y to be passed, but the target y is None")
    y = np.asarray(y)
    y_ndim = y.ndim
    if y_ndim not in (1, 2):
        raise RegressorInputError(f"y must be 1-D (N,) or 2-D (N, K); got shape {np.shape(y)}")
    Y = validate_X(np.reshape(y, (-1, 1)) if y_ndim == 1 else y, name="y")
    if Y.shape[0] != X.shape[0]:
        raise RegressorInputError(f"X has {X.shape[0]} samples but y has {Y.shape[0]}")
    if X.shape[0] < 2:
        raise RegressorInputError(f"need at least 2 training samples; got n_samples=1 (X of shape {X.shape})")
    return X, Y, y_ndim == 1


def check_basis_options(est) -> None:
    """Refuse (RegressorInputError, naming the option) bad basis, width or width_scale."""
    if est.basis not in BASIS_KINDS:
        raise RegressorInputError(f"basis={est.basis!r}; expected one of {BASIS_KINDS}")
    if est.width is not None and not (np.isfinite(est.width) and est.width > 0):
        raise RegressorInputError(f"width={est.width!r}; expected a positive number or None")
    if not (np.isfinite(est.width_scale) and est.width_scale > 0):
        raise RegressorInputError(f"width_scale={est.width_scale!r}; expected a positive number")


def fit_basis(est, X, y):
    """Fit the BasisRegressor est on X (N, D) and y (N,) or (N, K): its _fit_weights on the
    full basis of the training set (X itself, or a Gaussian kernel on every row); returns est."""
    check_basis_options(est)
    X, Y, y_1d = validate_Xy(X, y)
    est.n_features_in_ = X.shape[1]
    est.width_ = None
    if est.basis == "gaussian":
        est.width_ = (float(est.width) if est.width is not None
                      else default_width(X, est.width_scale))
    Phi = X if est.basis == "linear" else gaussian_design(X, X, est.width_)
    kept, coef, intercept = est._fit_weights(Phi, Y)
    est.relevance_ = np.asarray(kept, dtype=np.int64)
    est.coef_ = coef
    est.intercept_ = intercept
    est.centres_ = X[est.relevance_].copy() if est.basis == "gaussian" else None
    est._y_1d = y_1d
    return est
