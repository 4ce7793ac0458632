"""BasisRegressor: the scikit-learn-style base of the kernel regressors (regressor.rvm,
regressor.dls, regressor.sparse_rvm): a linear model on a basis (the inputs themselves, or
Gaussian kernels on centres), hyperparameters in the constructor, learned state ending in ``_``.
"""
from __future__ import annotations

import numpy as np

from .basis import (BASIS_KINDS, NotFittedError, Parameters, RegressorInputError,
                    default_width, gaussian_design, validate_X)


def design_matrix(X: np.ndarray, kind: str, centres: np.ndarray | None, width: float | None) -> np.ndarray:
    """Basis matrix Phi (N, M) for inputs X (N, D): X itself (linear) or the Gaussian kernel on centres."""
    if kind == "linear":
        return X
    return gaussian_design(X, centres, width)


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


class BasisRegressor(Parameters):
    """Shared plumbing for regressors of the form y = Phi(x)[:, kept] @ coef_ + intercept_.

    Subclasses implement ``_fit_weights(Phi (N, M), Y (N, K)) -> (kept indices (R,), coef (R, K),
    intercept (K,))`` on the full basis of the training set; this class handles validation, the
    basis, retained centres and prediction.
    """

    def __sklearn_tags__(self):
        # Called only by scikit-learn itself, so importing it here adds no run-time dependency.
        from sklearn.utils import Tags, RegressorTags, TargetTags, InputTags
        return Tags(estimator_type="regressor",
                    target_tags=TargetTags(required=True, multi_output=True, single_output=True),
                    regressor_tags=RegressorTags(), input_tags=InputTags())

    # --- fitting and prediction -----------------------------------------------------------
    def _check_basis_options(self) -> None:
        if self.basis not in BASIS_KINDS:
            raise RegressorInputError(f"basis={self.basis!r}; expected one of {BASIS_KINDS}")
        if self.width is not None and not (np.isfinite(self.width) and self.width > 0):
            raise RegressorInputError(f"width={self.width!r}; expected a positive number or None")
        if not (np.isfinite(self.width_scale) and self.width_scale > 0):
            raise RegressorInputError(f"width_scale={self.width_scale!r}; expected a positive number")

    def fit(self, X, y):
        """Fit on X (N, D) and y (N,) or (N, K); returns self."""
        self._check_basis_options()
        X, Y, y_1d = validate_Xy(X, y)
        self.n_features_in_ = X.shape[1]
        self.width_ = None
        if self.basis == "gaussian":
            self.width_ = float(self.width) if self.width is not None else default_width(X, self.width_scale)
        Phi = design_matrix(X, self.basis, X, self.width_)
        kept, coef, intercept = self._fit_weights(Phi, Y)
        self.relevance_ = np.asarray(kept, dtype=np.int64)
        self.coef_ = coef
        self.intercept_ = intercept
        self.centres_ = X[self.relevance_].copy() if self.basis == "gaussian" else None
        self._y_1d = y_1d
        return self

    def _check_fitted(self) -> None:
        if not hasattr(self, "coef_"):
            raise NotFittedError(f"this {type(self).__name__} is not fitted yet; call fit(X, y) first")

    def predict(self, X) -> np.ndarray:
        """Predict y for X (N, D): (N, K), or (N,) if fitted on a 1-D y."""
        self._check_fitted()
        X = validate_X(X, self.n_features_in_, owner=type(self).__name__)
        if self.basis == "linear":
            Phi = X[:, self.relevance_]
        else:
            Phi = gaussian_design(X, self.centres_, self.width_)
        Y = Phi @ self.coef_ + self.intercept_
        return Y[:, 0] if self._y_1d else Y

    def score(self, X, y) -> float:
        """Coefficient of determination R^2 averaged uniformly over outputs (scikit-learn convention)."""
        Y = np.asarray(y, dtype=np.float64).reshape(len(y), -1)
        P = self.predict(X).reshape(len(y), -1)
        ss_res = ((Y - P) ** 2).sum(0)
        ss_tot = ((Y - Y.mean(0)) ** 2).sum(0)
        with np.errstate(divide="ignore", invalid="ignore"):
            r2 = np.where(ss_tot > 0, 1.0 - ss_res / np.where(ss_tot > 0, ss_tot, 1.0),
                          np.where(ss_res > 0, 0.0, 1.0))
        return float(r2.mean())

    @property
    def n_basis_(self) -> int:
        """Number of retained basis functions (features or relevance vectors), excluding the offset."""
        self._check_fitted()
        return int(len(self.relevance_))
