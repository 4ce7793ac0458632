"""Damped least squares (ridge regression) over a linear or Gaussian-kernel basis.

W = argmin ||Y - Phi W - 1 b||^2 + lam_eff ||W||^2, the offset b unpenalised (solved by centring).
``lam`` is relative: lam_eff = lam * mean squared norm of the centred basis columns, so one value
means the same amount of damping whatever the descriptor scale or basis size.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg

from .basis import RegressorInputError
from .basis_regressor import BasisRegressor


class DLSRegressor(BasisRegressor):
    """Ridge regression y = Phi(x) @ coef_ + intercept_ (all basis functions kept).

    Parameters
    ----------
    basis : "linear" (Phi = x, D columns) or "gaussian" (one kernel per training example).
    lam : relative damping (> 0), see the module docstring.
    width : Gaussian kernel width in input units; None -> from the data scatter (see basis.py).
    width_scale : multiplier on the default squared width (ignored when ``width`` is given).

    Learned: coef_ (M, K), intercept_ (K,), relevance_ (M,) = all basis indices, centres_
    (M, D) for the Gaussian basis else None, width_ (float or None), n_features_in_.
    """

    def __init__(self, basis: str = "linear", lam: float = 1e-3, width: float | None = None,
                 width_scale: float = 1.0):
        self.basis = basis
        self.lam = lam
        self.width = width
        self.width_scale = width_scale

    def _fit_weights(self, Phi: np.ndarray, Y: np.ndarray):
        if not (np.isfinite(self.lam) and self.lam > 0):
            raise RegressorInputError(f"lam={self.lam!r}; expected a positive number")
        phi_mean, y_mean = Phi.mean(0), Y.mean(0)
        Pc, Yc = Phi - phi_mean, Y - y_mean
        G = Pc.T @ Pc
        scale = float(np.trace(G)) / G.shape[0]
        lam_eff = self.lam * (scale if scale > 0 else 1.0)
        G[np.diag_indices_from(G)] += lam_eff
        W = scipy.linalg.solve(G, Pc.T @ Yc, assume_a="pos")
        return np.arange(Phi.shape[1]), W, y_mean - phi_mean @ W
