"""Error and jitter measures (DESIGN.md), and blocked cross-validation for choosing hyperparameters.

Points: (T, 3P) arrays, x y z interleaved (point j is columns 3j..3j+2), in the data's units.
Angles: (T, A) arrays in degrees; differences are wrapped to (-180, 180] (regressor.angles.wrap_deg).
Every measure is computed per frame and then averaged over frames.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .angles import wrap_deg
from .errors import SilhouettePoseError


class MetricInputError(SilhouettePoseError, ValueError):
    """Arrays given to a metric have the wrong shape or non-finite values."""


def _check(est, true, name: str, min_frames: int = 1, points: bool = False) -> tuple[np.ndarray, np.ndarray]:
    est, true = np.asarray(est, dtype=np.float64), np.asarray(true, dtype=np.float64)
    if est.ndim != 2 or est.shape != true.shape:
        raise MetricInputError(f"{name}: estimate {est.shape} and truth {true.shape} must be equal (T, D) arrays")
    if points and est.shape[1] % 3:
        raise MetricInputError(f"{name}: {est.shape[1]} columns is not a multiple of 3 (x y z per point)")
    if est.shape[0] < min_frames:
        raise MetricInputError(f"{name}: needs at least {min_frames} frames; got {est.shape[0]}")
    if not (np.all(np.isfinite(est)) and np.all(np.isfinite(true))):
        raise MetricInputError(f"{name}: NaN or infinity in the input")
    return est, true


def _as_points(P: np.ndarray) -> np.ndarray:
    return P.reshape(P.shape[0], -1, 3)


def mean_point_error(est, true) -> float:
    """Mean over frames of the mean over points of ||est - true||; est, true (T, 3P). Data units."""
    est, true = _check(est, true, "mean_point_error", points=True)
    return float(np.linalg.norm(_as_points(est - true), axis=2).mean())


def point_jitter(P) -> float:
    """Mean over frames of the mean over points of ||p_{t+1} - 2 p_t + p_{t-1}||; P (T >= 3, 3P)."""
    P, _ = _check(P, P, "point_jitter", min_frames=3, points=True)
    d2 = P[2:] - 2.0 * P[1:-1] + P[:-2]
    return float(np.linalg.norm(_as_points(d2), axis=2).mean())


def angular_error(est, true) -> float:
    """The paper's eq. 5: mean over frames of the mean over angles of |wrap(est - true)|; degrees."""
    est, true = _check(est, true, "angular_error")
    return float(np.abs(wrap_deg(est - true)).mean())


def rms_per_angle(est, true) -> np.ndarray:
    """RMS over frames of wrap(est - true) for each angle: (T, A) -> (A,), degrees."""
    est, true = _check(est, true, "rms_per_angle")
    return np.sqrt((wrap_deg(est - true) ** 2).mean(0))


def _angle_second_difference(A: np.ndarray) -> np.ndarray:
    # Wrap each first difference, so a step across +-180 counts as the short way round.
    d1 = wrap_deg(np.diff(A, axis=0))
    return np.diff(d1, axis=0)


def angle_jitter(A) -> float:
    """Mean over frames and angles of |second difference| (wrap-aware); A (T >= 3, n) degrees."""
    A, _ = _check(A, A, "angle_jitter", min_frames=3)
    return float(np.abs(_angle_second_difference(A)).mean())


def acceleration_error(est, true) -> float:
    """angle_jitter of the wrapped difference wrap(est - true); est, true (T >= 3, n) degrees."""
    est, true = _check(est, true, "acceleration_error", min_frames=3)
    return float(np.abs(_angle_second_difference(wrap_deg(est - true))).mean())


def r2_score(predicted, y) -> float:
    """Coefficient of determination R^2 of predictions (N,) or (N, K) of y (the same shape),
    averaged uniformly over outputs (scikit-learn's convention: a constant output scores 1 if
    predicted exactly, else 0)."""
    Y = np.asarray(y, dtype=np.float64).reshape(len(y), -1)
    P = np.asarray(predicted).reshape(len(y), -1)
    ss_res = ((Y - P) ** 2).sum(0)
    ss_tot = ((Y - Y.mean(0)) ** 2).sum(0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r2 = np.where(ss_tot > 0, 1.0 - ss_res / np.where(ss_tot > 0, ss_tot, 1.0),
                      np.where(ss_res > 0, 0.0, 1.0))
    return float(r2.mean())


def contiguous_folds(n: int, n_folds: int) -> list[np.ndarray]:
    """Split range(n) into n_folds contiguous blocks (validation sets for time series)."""
    if not 2 <= n_folds <= n:
        raise MetricInputError(f"n_folds={n_folds}; expected 2 <= n_folds <= n = {n}")
    return [b for b in np.array_split(np.arange(n), n_folds)]


def cross_validate(make_model: Callable[[], object], X: np.ndarray, Y: np.ndarray,
                   folds: list[np.ndarray], error: Callable = mean_point_error) -> tuple[float, list]:
    """Fit make_model() without each fold and score it on the fold.

    X (N, D), Y (N, K); folds: index arrays. Returns (error averaged over held-out frames, i.e.
    fold errors weighted by fold size; the fitted models, one per fold).
    """
    total, count, models = 0.0, 0, []
    for hold in folds:
        train = np.ones(len(X), bool)
        train[hold] = False
        model = make_model().fit(X[train], Y[train])
        total += error(model.predict(X[hold]), Y[hold]) * len(hold)
        count += len(hold)
        models.append(model)
    return total / count, models
