"""BasisRegressor: the scikit-learn-style base of the kernel regressors (regressor.rvm,
regressor.dls, regressor.sparse_rvm): a linear model on a basis (regressor.basis)."""
from __future__ import annotations

import numpy as np

from .basis import Parameters, gaussian_design, validate_X


class BasisRegressor(Parameters):
    """Regressors y = Phi(x)[:, kept] @ coef_ + intercept_. Subclasses implement
    ``_fit_weights(Phi (N, M), Y (N, K)) -> (kept (R,), coef (R, K), intercept (K,))`` on the
    training set's full basis (regressor.basis_fit); this class does the rest."""

    def __sklearn_tags__(self):
        # Called only by scikit-learn itself, so importing it here adds no run-time dependency.
        from sklearn.utils import Tags, RegressorTags, TargetTags, InputTags
        return Tags(estimator_type="regressor",
                    target_tags=TargetTags(required=True, multi_output=True, single_output=True),
                    regressor_tags=RegressorTags(), input_tags=InputTags())

    def fit(self, X, y):
        """Fit on X (N, D) and y (N,) or (N, K) (regressor.basis_fit); returns self."""
        from .basis_fit import fit_basis
        return fit_basis(self, X, y)

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
        """R^2 of predict(X) against y, averaged over outputs (regressor.metrics.r2_score)."""
        from .metrics import r2_score
        return r2_score(self.predict(X), y)

    @property
    def n_basis_(self) -> int:
        """Number of retained basis functions (features or relevance vectors), excluding the offset."""
        self._check_fitted()
        return int(len(self.relevance_))
