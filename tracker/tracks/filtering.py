"""Kalman filtering of regressed poses over time, with angle wrap-around handled.

State x (108,): the 54 angles (heading, then pose entries 2..54), degrees, then their rates.
Constant velocity, piecewise-constant white acceleration (dt = 1/fps):

    F = [[I, dt I], [0, I]]      Q = diag(q) (x) [[dt^4/4, dt^3/2], [dt^3/2, dt^2]]
    H = [I, 0]                   R = measurement covariance (54, 54), degrees^2

q: acceleration variances, (deg/s^2)^2 (a model file has its own q and R, else the defaults).
Measured angles are unwrapped against the prediction. A raw pose whose heading norm is below
``ambiguity_threshold`` averaged several views: its R is inflated, most on the heading.
"""
from __future__ import annotations

import copy
import weakref
from collections.abc import Callable, Sequence

import numpy as np
import scipy.linalg

from regressor.angles import N_ANGLES, POSE_DIM, angles_to_pose, heading_norm, pose_angles, wrap_deg
from regressor.pose_model import DEFAULT_AMBIGUITY_THRESHOLD
from regressor.errors import SilhouettePoseError

DEFAULT_ACCEL_STD = 1000.0        # deg/s^2: median RMS second difference, 12 CMU clips (30 fps)
DEFAULT_JOINT_STD = 6.0           # deg, each joint angle (the paper's error level)
DEFAULT_HEADING_STD = 20.0        # deg (the paper's error level)
_LOG_2PI = float(np.log(2.0 * np.pi))
DEFAULT_RATE_STD = 90.0           # deg/s, prior on angular rates when a track starts


class FilterError(SilhouettePoseError, ValueError):
    """Bad filter settings or pose vectors; one-line message naming the problem."""


def initial_state(z: np.ndarray, R: np.ndarray, rate_std: float) -> tuple[np.ndarray, np.ndarray]:
    """A first state: x (2n,) = [z (n,), zero rates], P (2n, 2n) = diag(R, rate_std^2 I)."""
    n = len(z)
    return np.concatenate([z, np.zeros(n)]), scipy.linalg.block_diag(R, np.eye(n) * rate_std**2)


class ConstantVelocityFilter:
    """Kalman filter and RTS smoother for ``dim`` values, each with its rate (module docstring).
    R: measurement covariance (dim,) or (dim, dim), units^2 (or one per measurement); q:
    acceleration variances, scalar or (dim,), (units/s^2)^2; rate_std: the rates' prior std at
    the first frame, units/s; align(z (dim,), predicted (dim,)) -> z: e.g. angles unwrapped."""

    def __init__(self, dim: int, fps: float, R, q, rate_std: float,
                 align: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None):
        if not (int(dim) == dim and dim >= 1):
            raise FilterError(f"dim={dim} must be a positive integer")
        if not (np.isfinite([fps, rate_std]).all() and min(fps, rate_std) > 0):
            raise FilterError(f"fps={fps} and rate_std={rate_std} must be positive")
        q = np.broadcast_to(np.asarray(q, float), (int(dim),))
        if not (np.isfinite(q).all() and (q >= 0).all()):
            raise FilterError("q (acceleration variances) must be finite and >= 0")
        R = np.asarray(R, float)
        R = np.diag(R) if R.shape == (dim,) else R
        if R.shape != (dim, dim):
            raise FilterError(f"R must have shape ({dim},) or ({dim}, {dim}), got {R.shape}")
        if not np.isfinite(R).all() or not np.allclose(R, R.T) or np.linalg.eigvalsh(R).min() <= 0:
            raise FilterError("R must be finite, symmetric and positive definite")
        self.dim, self.fps, self.dt = int(dim), float(fps), 1.0 / float(fps)
        self.R, self.q, self.rate_std, self.align = R, q.copy(), float(rate_std), align
        dt = self.dt
        self.Q = np.block([[np.diag(q * dt**4 / 4), np.diag(q * dt**3 / 2)],
                           [np.diag(q * dt**3 / 2), np.diag(q * dt**2)]])

    def smooth(self, zs: np.ndarray, Rs: Sequence | None = None, window: int = 256,
               lag: int = 64) -> np.ndarray:
        """Forward filter then Rauch-Tung-Striebel smoothing (filterpy's to rounding): values
        (T, dim) of zs (T, dim). The filtered covariances are kept per window of ``window``
        frames, each run on ``lag`` further frames whose influence on it has decayed."""
        zs = self._check_sequence(zs)
        if window < 1 or lag < 0:
            raise FilterError(f"window={window} must be >= 1 and lag={lag} >= 0")
        n, dt = self.dim, self.dt
        smoothed = np.empty_like(zs)
        x = P = None
        for start in range(0, len(zs), window):
            stop = min(start + window + lag, len(zs))
            xs = np.empty((stop - start, 2 * n))
            ps = np.empty((stop - start, 2 * n, 2 * n))
            for i, t in enumerate(range(start, stop)):
                R = self.R if Rs is None or Rs[t] is None else Rs[t]
                if x is None:
                    x, P = initial_state(zs[t], R, self.rate_std)
                else:
                    x, P = self._predict(x, P)
                    z = zs[t] if self.align is None else self.align(zs[t], x[:n])
                    K = _spd_solve(P[:n, :n] + R, P[:n, :]).T            # (2n, n)
                    x = x + K @ (z - x[:n])
                    P = P - K @ P[:n, :]
                    P = (P + P.T) / 2.0
                xs[i], ps[i] = x, P
                if i + 1 == window:
                    resume = (x.copy(), P.copy())   # the next window continues from here
            out = xs.copy()
            for k in range(len(xs) - 2, -1, -1):
                x_pred, P_pred = self._predict(xs[k], ps[k])
                gain = _spd_solve(P_pred, out[k + 1] - x_pred)
                # P_k F' gain, with F' gain = [g1, dt g1 + g2]
                out[k] = xs[k] + ps[k] @ np.concatenate([gain[:n], dt * gain[:n] + gain[n:]])
            end = min(start + window, len(zs))
            smoothed[start:end] = out[: end - start, :n]
            if stop > start + window:
                x, P = resume
        return smoothed

    def _predict(self, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x (2n,), P (2n, 2n) one frame ahead: F x and F P F' + Q."""
        return self._predict_state(x), self._predict_covariance(P)

    def _predict_state(self, x: np.ndarray) -> np.ndarray:
        """F x (2n,) of a state x (2n,)."""
        n = self.dim
        return np.concatenate([x[:n] + self.dt * x[n:], x[n:]])

    def _predict_covariance(self, P: np.ndarray) -> np.ndarray:
        """F P F' + Q (2n, 2n) of a covariance P (2n, 2n), by F's blocks (O(n^2))."""
        n, dt = self.dim, self.dt
        B, D = P[:n, n:], P[n:, n:]
        out = P + self.Q
        out[:n, :n] += dt * (B + P[n:, :n]) + dt * dt * D
        dD = dt * D
        out[:n, n:] += dD
        out[n:, :n] += dD
        return out

    def _check_sequence(self, zs) -> np.ndarray:
        zs = np.asarray(zs, float)
        if zs.ndim != 2 or zs.shape[1] != self.dim or len(zs) == 0:
            raise FilterError(f"measurements must have shape (T, {self.dim}), got {zs.shape}")
        if not np.isfinite(zs).all():
            raise FilterError("measurements contain NaN or infinity")
        return zs


# LAPACK directly: scipy's wrappers check and copy more than a per-frame filter can afford.
_trtrs, _potrf, _potrs = scipy.linalg.lapack.get_lapack_funcs(("trtrs", "potrf", "potrs"),
                                                               dtype=np.float64)


def _lapack(result: tuple, problem: str) -> np.ndarray:
    """A LAPACK call's (out, info) -> out; a FilterError naming the problem unless info is 0."""
    out, info = result
    if info != 0:
        raise FilterError(f"{problem} (LAPACK info {info})")
    return out


def _lower_solve(L: np.ndarray, b: np.ndarray) -> np.ndarray:
    """L^-1 b for a lower-triangular L (n, n) and b (n,) or (n, m)."""
    return _lapack(_trtrs(L, b, lower=1), "singular innovation covariance")


def _spd_solve(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A^-1 b for a symmetric positive definite A (n, n) and b (n,) or (n, m) (Cholesky)."""
    c = _lapack(_potrf(A, lower=1), "covariance not positive definite")
    return _lapack(_potrs(c, b, lower=1), "covariance solve failed")


def _unwrap_against(z: np.ndarray, predicted: np.ndarray) -> np.ndarray:
    """Angles z (deg) shifted by whole turns to lie within 180 deg of predicted."""
    return predicted + wrap_deg(z - predicted)


class _Covariance:
    """A state covariance P (108, 108) and what follows from it alone (its prediction; per
    ambiguity the innovation factor and update), computed once for all filters holding it (a
    track's hypotheses' copies): it depends on the ambiguous flags, never on measured values."""

    __slots__ = ("P", "_predicted", "factors", "updates", "__weakref__")

    def __init__(self, P: np.ndarray):
        self.P, self._predicted = P, None
        self.factors: dict = {}     # ambiguous -> (L, log det)
        self.updates: dict = {}     # ambiguous -> (W, the next _Covariance)

    def predicted(self, cv: ConstantVelocityFilter) -> np.ndarray:
        """P_pred = F P F' + Q (108, 108) of cv's model, once."""
        if self._predicted is None:
            self._predicted = cv._predict_covariance(self.P)
        return self._predicted


class PoseKalmanFilter:
    """Per-track Kalman filter over the 54 pose angles (see the module docstring): R (54,) or
    (54, 54) deg^2 in :func:`regressor.angles.pose_angles` order (None: the defaults), q and
    rate_std as ConstantVelocityFilter's in degrees. A frame whose heading norm is below
    ``ambiguity_threshold`` has its R scaled by the ambiguous factors (heading, other angles)."""

    def __init__(self, fps: float, R=None, q=None,
                 ambiguity_threshold: float = DEFAULT_AMBIGUITY_THRESHOLD,
                 ambiguous_heading_factor: float = 25.0, ambiguous_joint_factor: float = 4.0,
                 rate_std: float = DEFAULT_RATE_STD):
        if min(ambiguous_heading_factor, ambiguous_joint_factor) < 1 or ambiguity_threshold < 0:
            raise FilterError("ambiguous factors must be >= 1 and ambiguity_threshold >= 0")
        if R is None:
            R = np.diag(np.r_[DEFAULT_HEADING_STD, np.full(N_ANGLES - 1, DEFAULT_JOINT_STD)]**2)
        self.cv = ConstantVelocityFilter(N_ANGLES, fps, R,
                                         DEFAULT_ACCEL_STD**2 if q is None else q, rate_std,
                                         align=_unwrap_against)
        self.R = self.cv.R
        inflate = np.sqrt(np.r_[ambiguous_heading_factor,
                                np.full(N_ANGLES - 1, ambiguous_joint_factor)])
        # Scaling std per angle keeps correlations: R_amb = D R D with D = diag(sqrt(factor)).
        self.R_ambiguous = self.R * np.outer(inflate, inflate)
        self.ambiguity_threshold = ambiguity_threshold
        self._x: np.ndarray | None = None        # (108,) state, None before the first step
        self._x_pred: np.ndarray | None = None   # (108,) its prediction, once per frame
        self._cov: _Covariance | None = None     # its covariance (108, 108), shared
        # The first covariance by ambiguity while a filter holds it, shared by copies.
        self._start: dict[bool, weakref.ref] = {}

    def _measure(self, raw55) -> tuple[np.ndarray, np.ndarray, bool]:
        """Check one raw pose (55,) -> (angles (54,), its R, ambiguous)."""
        raw = np.asarray(raw55, float)
        if raw.shape != (POSE_DIM,):
            raise FilterError(f"pose vector must have shape (55,), got {raw.shape}")
        if not np.isfinite(raw).all():
            bad = np.flatnonzero(~np.isfinite(raw)).tolist()
            raise FilterError(f"pose vector has non-finite entries at {bad}")
        ambiguous = bool(heading_norm(raw) < self.ambiguity_threshold)
        return pose_angles(raw), self.R_ambiguous if ambiguous else self.R, ambiguous

    def log_likelihoods(self, raws) -> np.ndarray:
        """Innovation log-likelihoods (K,) of candidate raw poses (K, 55) for the next frame
        (zeros before the first step); the filter keeps its state and the prediction."""
        raws = np.asarray(raws, float)
        if self._x is None:
            return np.zeros(len(raws))
        x_pred = self._prediction()
        angles, ambiguous = self._measure_rows(raws)
        offsets = wrap_deg(angles - x_pred[:N_ANGLES])                  # (K, 54)
        out = np.empty(len(raws))
        for k, flag in enumerate(ambiguous.tolist()):
            L, logdet = self._factor(flag)
            w = _lower_solve(L, offsets[k])
            out[k] = float(-0.5 * (w @ w + logdet + N_ANGLES * _LOG_2PI))
        return out

    def _measure_rows(self, raws: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """_measure of each raw pose of raws (K, 55) at once -> (angles (K, 54), ambiguous
        (K,) bool); FilterError naming the first bad row's problem, as _measure's."""
        if raws.ndim != 2 or raws.shape[1] != POSE_DIM:
            raise FilterError(f"pose vector must have shape (55,), got {raws.shape[1:]}")
        finite = np.isfinite(raws)
        if not finite.all():
            row = int(np.flatnonzero(~finite.all(axis=1))[0])
            self._measure(raws[row])                     # raises, naming the entries
        return pose_angles(raws), heading_norm(raws) < self.ambiguity_threshold

    def _prediction(self) -> np.ndarray:
        """x_pred (108,) of the next frame, once."""
        if self._x_pred is None:
            self._x_pred = self.cv._predict_state(self._x)
        return self._x_pred

    def _factor(self, ambiguous: bool) -> tuple[np.ndarray, float]:
        """Lower Cholesky factor of H P_pred H' + R (54, 54) and its log-determinant (cached)."""
        cov = self._cov
        if ambiguous not in cov.factors:
            R = self.R_ambiguous if ambiguous else self.R
            L = _lapack(_potrf(cov.predicted(self.cv)[:N_ANGLES, :N_ANGLES] + R, lower=1,
                               clean=1), "innovation covariance not positive definite")
            cov.factors[ambiguous] = (L, 2.0 * np.log(np.diag(L)).sum())
        return cov.factors[ambiguous]

    def _update(self, ambiguous: bool) -> tuple[np.ndarray, "_Covariance"]:
        """(W = L^-1 H P_pred (54, 108), the covariance after the update P_pred - W'W), cached
        with the covariance: it does not depend on the measurement."""
        cov = self._cov
        if ambiguous not in cov.updates:
            L, _ = self._factor(ambiguous)
            P_pred = cov.predicted(self.cv)
            W = _lower_solve(L, P_pred[:N_ANGLES])
            cov.updates[ambiguous] = (W, _Covariance(P_pred - W.T @ W))
        return cov.updates[ambiguous]

    def _first(self, R: np.ndarray, ambiguous: bool) -> "_Covariance":
        """The first covariance diag(R, rate_std^2 I), shared by copies (weakly: not kept old)."""
        held = self._start.get(ambiguous)
        cov = None if held is None else held()
        if cov is None:
            n = N_ANGLES
            cov = _Covariance(initial_state(np.zeros(n), R, self.cv.rate_std)[1])
            self._start[ambiguous] = weakref.ref(cov)
        return cov

    def copy(self) -> "PoseKalmanFilter":
        """A cheap independent copy: it shares the covariance (steps replace it, never alter it)."""
        return copy.copy(self)

    def step(self, raw55) -> tuple[np.ndarray, bool]:
        """Filter one raw regressor output (55,) -> (filtered pose (55,), ambiguous flag)."""
        angles, R, ambiguous = self._measure(raw55)
        n = N_ANGLES
        if self._x is None:
            self._x, self._cov = np.concatenate([angles, np.zeros(n)]), self._first(R, ambiguous)
        else:
            x_pred = self._prediction()
            L, _ = self._factor(ambiguous)
            # With S = L L' and W = L^-1 H P_pred (54, 108): K = P_pred H' S^-1 = W' L^-1, so
            # x = x_pred + W' L^-1 y and K S K' = W' W (one triangular solve, exactly symmetric).
            W, self._cov = self._update(ambiguous)
            x = x_pred + W.T @ _lower_solve(L, wrap_deg(angles - x_pred[:n]))
            # Whole turns change nothing (measurements are unwrapped) and keep the state bounded.
            x[:n] -= 360.0 * np.round(x[:n] / 360.0)
            self._x = x
        self._x_pred = None
        return angles_to_pose(self._x[:n]), ambiguous

    def rts_smooth(self, raws: Sequence | np.ndarray, window: int = 256,
                   lag: int = 64) -> np.ndarray:
        """RTS-smoothed poses (T, 55) of a whole track raws (T, 55); the step state is untouched."""
        angles, Rs, _ = self._measure_all(raws, "rts_smooth")
        return angles_to_pose(self.cv.smooth(angles, Rs, window=window, lag=lag))

    def _measure_all(self, raws, name: str) -> tuple[np.ndarray, list, np.ndarray]:
        """Checked raw poses (T, 55) -> (angles (T, 54), their R each, ambiguous (T,) bool)."""
        raws = np.asarray(raws, float)
        if raws.ndim != 2 or raws.shape[1] != POSE_DIM or len(raws) == 0:
            raise FilterError(f"{name} needs poses of shape (T, 55), got {raws.shape}")
        angles, Rs, ambiguous = zip(*(self._measure(raw) for raw in raws))
        return np.array(angles), list(Rs), np.array(ambiguous, bool)
