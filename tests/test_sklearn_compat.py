"""The regressors pass scikit-learn's estimator checks (scikit-learn is a test-only dependency)."""
import pytest

sklearn_checks = pytest.importorskip("sklearn.utils.estimator_checks")

from regressor.dls import DLSRegressor
from regressor.rvm import RVMRegressor
from regressor.sparse_rvm import SparseRVMRegressor

# Checks that conflict with the design, each with the reason (passed to check_estimator).
EXPECTED_FAILED = {
    "check_estimators_unfitted":
        "predict before fit raises regressor.basis.NotFittedError (a ValueError and AttributeError, "
        "like scikit-learn's) rather than sklearn.exceptions.NotFittedError itself, because "
        "scikit-learn is not a run-time dependency",
}


@pytest.mark.parametrize("estimator", [
    DLSRegressor(basis="linear"), DLSRegressor(basis="gaussian"),
    RVMRegressor(basis="linear"), RVMRegressor(basis="gaussian", max_iter=200),
    SparseRVMRegressor(n_candidates=20),
], ids=repr)
@pytest.mark.slow
def test_passes_sklearn_estimator_checks(estimator):
    sklearn_checks.check_estimator(estimator, expected_failed_checks=EXPECTED_FAILED)
