"""Fitting the side classifier (regressor.side_classifier.SideClassifier): scikit-learn's
MLPClassifier (the ``train`` extra), its layers kept as plain arrays. Training only; ``track``
loads regressor.side_classifier alone.
"""
from __future__ import annotations

import time
import warnings
from typing import Callable

import numpy as np

from .side_classifier import MAX_LAYERS, SideClassifier


def facing_camera(heading_deg: np.ndarray) -> np.ndarray:
    """The classifier's label (N,) bool: the heading (N,) degrees is in the camera's half
    (|heading| <= 90)."""
    return np.abs(np.asarray(heading_deg, dtype=np.float64)) <= 90.0


def fit_side_classifier(X: np.ndarray, heading_deg: np.ndarray,
                        hidden: tuple[int, ...] = (128,), alpha: float = 1e-3,
                        max_iter: int = 200, seed: int = 0,
                        log: Callable[[str], None] = lambda message: None) -> SideClassifier:
    """Fit a :class:`SideClassifier` on inputs X (N, P) labelled by the true headings
    heading_deg (N,) (front: |heading| <= 90) with scikit-learn's MLPClassifier (Adam,
    minibatches of 256, L2 alpha, 10 % held out for early stopping after 10 epochs without
    gain; seeded). Needs scikit-learn (training only)."""
    if not 1 <= len(hidden) + 1 <= MAX_LAYERS:
        raise ValueError(f"a side classifier has 0..{MAX_LAYERS - 1} hidden layers, got "
                         f"{len(hidden)}")
    try:
        from sklearn.exceptions import ConvergenceWarning
        from sklearn.neural_network import MLPClassifier
    except ImportError:
        raise ValueError("fitting the side classifier needs scikit-learn: "
                         "pip install -e '.[train]'") from None
    X = np.asarray(X, dtype=np.float64)
    front = facing_camera(heading_deg).astype(int)
    if len(np.unique(front)) < 2:
        raise ValueError("the side classifier needs poses facing both halves")
    x_mean, x_scale = X.mean(axis=0), float(X.std(axis=0).mean())
    start = time.perf_counter()
    net = MLPClassifier(hidden_layer_sizes=tuple(hidden), alpha=alpha, batch_size=256,
                        max_iter=max_iter, early_stopping=True, n_iter_no_change=10,
                        random_state=seed)
    with warnings.catch_warnings():          # max_iter reached is reported below, not warned
        warnings.simplefilter("ignore", ConvergenceWarning)
        net.fit((X - x_mean) / x_scale, front)
    stopped = "max_iter reached" if net.n_iter_ >= max_iter else "early stop"
    log(f"  side classifier: {net.n_iter_} epochs ({stopped}), held-out accuracy "
        f"{net.best_validation_score_:.3f}, {time.perf_counter() - start:.0f} s")
    return SideClassifier(list(zip(net.coefs_, net.intercepts_)), x_mean, x_scale)
