"""Basis functions for pose regression, and the estimator plumbing the regressors share.

A regressor predicts ``y = phi(x) @ W + b``. Two bases:

- ``"linear"``: ``phi(x) = x`` (D columns); a sparse fit selects descriptor *features*.
- ``"gaussian"``: ``phi(x)_j = exp(-||x - c_j||^2 / width^2)`` with one centre per training
  example (N columns); a sparse fit selects training *examples* (relevance vectors).

The constant offset ``b`` is always fitted and never penalised. Kernel width: by default
``width^2 = width_scale * mean squared distance between training points`` (estimated on at most
``_WIDTH_SAMPLE`` rows), so ``width_scale`` is a dimensionless knob that transfers between
descriptor scalings and stacking depths.

The estimators follow the scikit-learn contract without importing scikit-learn: the constructor
stores hyperparameters only, ``fit`` returns ``self``, learned state ends in ``_``, ``predict`` is
pure, and ``get_params``/``set_params`` are written out here.
"""
from __future__ import annotations

import inspect

import numpy as np

from .errors import SilhouettePoseError

BASIS_KINDS = ("linear", "gaussian")
_WIDTH_SAMPLE = 2000  # rows used to estimate the mean squared distance (deterministic: evenly spaced)


class RegressorInputError(SilhouettePoseError, ValueError):
    """Bad input to a regressor (shape, dtype, non-finite values, unknown option)."""


class RegressorTypeError(RegressorInputError, TypeError):
    """Input that is not numbers at all (e.g. objects in X)."""


class NotFittedError(SilhouettePoseError, ValueError, AttributeError):
    """``predict`` (or a learned attribute) was used before ``fit``."""


def squared_distances(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Squared Euclidean distances, (n, D) x (m, D) -> (n, m), clipped at 0 against round-off."""
    d2 = (A * A).sum(1)[:, None] + (B * B).sum(1)[None, :] - 2.0 * (A @ B.T)
    return np.maximum(d2, 0.0)


def nearest_columns(d2: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The k smallest entries of each row of d2 (n, N), nearest first (k <= N): their column
    indices (n, k) int and values (n, k). For a block of squared distances from n queries to
    N rows (regressor.heading_index, regressor.mixture.NeighbourGate)."""
    nearest = (np.argpartition(d2, k - 1, axis=1)[:, :k] if k < d2.shape[1]
               else np.broadcast_to(np.arange(k), (len(d2), k)))
    near_d2 = np.take_along_axis(d2, nearest, axis=1)
    order = np.argsort(near_d2, axis=1)
    return np.take_along_axis(nearest, order, axis=1), np.take_along_axis(near_d2, order, axis=1)


def default_width(X: np.ndarray, width_scale: float = 1.0) -> float:
    """Kernel width from the data's scatter: sqrt(width_scale * mean ||x_i - x_j||^2).

    X: (N, D) training inputs. mean ||x_i - x_j||^2 over all pairs equals 2 * total variance,
    computed exactly in O(N D) (no pairwise matrix). Returns a positive float (units of X).
    """
    mean_sq = 2.0 * float(np.var(X, axis=0).sum())
    if not mean_sq > 0.0:
        raise RegressorInputError("cannot set a kernel width: all training inputs are identical")
    return float(np.sqrt(width_scale * mean_sq))


def gaussian_design(X: np.ndarray, centres: np.ndarray, width: float) -> np.ndarray:
    """Gaussian kernel design matrix: (N, D), (M, D) -> (N, M), exp(-||x - c||^2 / width^2)."""
    return np.exp(-squared_distances(X, centres) / (width * width))


def design_matrix(X: np.ndarray, kind: str, centres: np.ndarray | None, width: float | None) -> np.ndarray:
    """Basis matrix Phi (N, M) for inputs X (N, D): X itself (linear) or the Gaussian kernel on centres."""
    if kind == "linear":
        return X
    return gaussian_design(X, centres, width)


def validate_X(X, n_features: int | None = None, name: str = "X", owner: str = "the model") -> np.ndarray:
    """Check X is a finite 2-D real array (N, D) (D = n_features if given); return it as float64.

    Messages include scikit-learn's standard phrases so its estimator checks recognise them.
    """
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


class BasisRegressor:
    """Shared plumbing for regressors of the form y = Phi(x)[:, kept] @ coef_ + intercept_.

    Subclasses implement ``_fit_weights(Phi (N, M), Y (N, K)) -> (kept indices (R,), coef (R, K),
    intercept (K,))`` on the full basis of the training set; this class handles validation, the
    basis, retained centres and prediction.
    """

    # --- scikit-learn parameter protocol, by hand -------------------------------------------
    @classmethod
    def _param_names(cls) -> list[str]:
        sig = inspect.signature(cls.__init__)
        return [p for p in sig.parameters if p != "self"]

    def get_params(self, deep: bool = True) -> dict:
        """Constructor hyperparameters as a dict (scikit-learn protocol)."""
        return {name: getattr(self, name) for name in self._param_names()}

    def set_params(self, **params):
        """Set constructor hyperparameters by name; returns self (scikit-learn protocol)."""
        valid = self._param_names()
        for name, value in params.items():
            if name not in valid:
                raise RegressorInputError(f"{type(self).__name__} has no parameter {name!r}; valid: {valid}")
            setattr(self, name, value)
        return self

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"

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
