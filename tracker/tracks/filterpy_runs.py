"""ConstantVelocityFilter run by filterpy's KalmanFilter (and rts_smoother): the forward filter
of the evaluations, and the reference the tests hold ConstantVelocityFilter.smooth to. Loaded
only by those (``track`` never is)."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from filterpy.kalman import KalmanFilter

from tracker.tracks.filtering import ConstantVelocityFilter, initial_state


def _steps(cv: ConstantVelocityFilter, zs: np.ndarray, Rs: Sequence | None):
    """filterpy's filter over checked measurements zs (T, dim); Rs: per-frame R or None. Yields
    it after each frame's update (the same KalmanFilter object each time)."""
    n = cv.dim
    kf = KalmanFilter(dim_x=2 * n, dim_z=n)
    kf.F, kf.H, kf.Q, kf.R = _F(cv), np.eye(n, 2 * n), cv.Q, cv.R
    for t, z in enumerate(zs):
        R = cv.R if Rs is None or Rs[t] is None else Rs[t]
        if t == 0:
            x, kf.P = initial_state(z, R, cv.rate_std)
            kf.x = x[:, None]
        else:
            kf.predict()
            if cv.align is not None:
                z = cv.align(z, kf.x[:n, 0])
            kf.update(z[:, None], R=R)
        yield kf


def _F(cv: ConstantVelocityFilter) -> np.ndarray:
    """The transition matrix [[I, dt I], [0, I]] (2 dim, 2 dim)."""
    eye = np.eye(cv.dim)
    return np.block([[eye, cv.dt * eye], [np.zeros_like(eye), eye]])


def forward(cv: ConstantVelocityFilter, zs: np.ndarray, Rs: Sequence | None = None
            ) -> np.ndarray:
    """Forward-filtered values (T, dim) of measurements zs (T, dim); Rs: per-frame R or None."""
    return np.array([kf.x[: cv.dim, 0].copy() for kf in _steps(cv, cv._check_sequence(zs), Rs)])


def smooth(cv: ConstantVelocityFilter, zs, Rs: Sequence | None = None) -> np.ndarray:
    """What ConstantVelocityFilter.smooth computes, by filterpy's filter and rts_smoother in
    one window: values (T, dim) of measurements zs (T, dim)."""
    zs = cv._check_sequence(zs)
    xs, ps = [], []
    for kf in _steps(cv, zs, Rs):
        xs.append(kf.x.copy())
        ps.append(kf.P.copy())
    x_smooth, _, _, _ = kf.rts_smoother(np.array(xs), np.array(ps), Fs=[_F(cv)] * len(xs),
                                        Qs=[cv.Q] * len(xs))
    return x_smooth[:, : cv.dim, 0]
