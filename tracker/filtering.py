"""Kalman filtering of regressed poses over time (filterpy), with angle wrap-around handled.

State: for each of the 54 angles (heading, then the 53 angles of pose entries 2..54), in degrees,
the angle and its rate; laid out as x = [angles (54), rates (54)] (108,). Constant-velocity
model with piecewise-constant white acceleration per frame (dt = 1/fps):

    F = [[I, dt I], [0, I]]      Q = diag(q) (x) [[dt^4/4, dt^3/2], [dt^3/2, dt^2]]
    H = [I, 0]                   R = measurement covariance (54, 54), degrees^2

``q`` is the variance of angular acceleration, (deg/s^2)^2. Defaults: acceleration std 1000
deg/s^2 (the median over angles of the RMS second difference in 12 CMU clips at 30 fps, measured
on this project's data), measurement std 6 deg per joint angle and 20 deg for the heading
(the paper's reported error levels); a model file should supply its own.

Wrap-around: the state is continuous (no jump at +-180). Each measured angle is unwrapped to lie
within 180 deg of the predicted angle before the update; outputs are wrapped to (-180, 180].

Ambiguity: a raw pose whose heading norm ||(cos, sin)|| is below ``ambiguity_threshold`` comes
from a silhouette the regressor could not disambiguate (it averaged several headings, e.g. front
and back views). Its R is inflated by ``ambiguous_heading_factor`` (default 25, i.e. 5x the std)
on the heading and by ``ambiguous_joint_factor`` (default 4, 2x the std) on the other angles,
because a front/back confusion also swaps left and right limbs, but less badly.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from filterpy.kalman import KalmanFilter

from sequences.pose_vector import POSE_DIM

N_ANGLES = 54
DEFAULT_ACCEL_STD = 1000.0        # deg/s^2
DEFAULT_JOINT_STD = 6.0           # deg
DEFAULT_HEADING_STD = 20.0        # deg
DEFAULT_RATE_STD = 90.0           # deg/s, prior on angular rates when a track starts


class FilterError(ValueError):
    """Bad filter settings or pose vectors; one-line message naming the problem."""


def wrap_deg(angles: np.ndarray) -> np.ndarray:
    """Angles in degrees, any shape -> the same angles in (-180, 180]."""
    return 180.0 - np.mod(180.0 - np.asarray(angles, float), 360.0)


def pose_to_angles(raw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pose vectors (..., 55) -> (angles (..., 54) deg, heading norm (...)).

    angles[..., 0] = atan2(sin, cos) heading; angles[..., 1:] = raw[..., 2:55].
    """
    raw = np.asarray(raw, float)
    heading = np.degrees(np.arctan2(raw[..., 1], raw[..., 0]))
    return (np.concatenate([heading[..., None], raw[..., 2:]], axis=-1),
            np.hypot(raw[..., 0], raw[..., 1]))


def angles_to_pose(angles: np.ndarray) -> np.ndarray:
    """Angles (..., 54) deg -> pose vectors (..., 55): heading as unit (cos, sin), the rest
    wrapped to (-180, 180]."""
    angles = np.asarray(angles, float)
    heading = np.radians(angles[..., 0])
    return np.concatenate([np.cos(heading)[..., None], np.sin(heading)[..., None],
                           wrap_deg(angles[..., 1:])], axis=-1)


def _as_covariance(R, name: str) -> np.ndarray:
    """R given as None, (54,) variances or (54, 54) -> a checked (54, 54) covariance, deg^2."""
    if R is None:
        std = np.full(N_ANGLES, DEFAULT_JOINT_STD)
        std[0] = DEFAULT_HEADING_STD
        return np.diag(std**2)
    R = np.asarray(R, float)
    if R.shape == (N_ANGLES,):
        R = np.diag(R)
    if R.shape != (N_ANGLES, N_ANGLES):
        raise FilterError(f"{name} must have shape (54,) or (54, 54), got {R.shape}")
    if not np.isfinite(R).all() or not np.allclose(R, R.T) or np.linalg.eigvalsh(R).min() <= 0:
        raise FilterError(f"{name} must be finite, symmetric and positive definite")
    return R


class PoseKalmanFilter:
    """Per-track Kalman filter over the 54 pose angles (see the module docstring).

    ``fps``: frames per second (dt = 1/fps). ``R``: measurement covariance, (54,) variances or
    (54, 54), deg^2, angle order as :func:`pose_to_angles`. ``q``: acceleration variances, scalar
    or (54,), (deg/s^2)^2. ``ambiguity_threshold``: heading norm below which a frame is ambiguous.
    ``rate_std``: prior std of the angular rates at the first frame, deg/s.
    """

    def __init__(self, fps: float, R=None, q=None, ambiguity_threshold: float = 0.5,
                 ambiguous_heading_factor: float = 25.0, ambiguous_joint_factor: float = 4.0,
                 rate_std: float = DEFAULT_RATE_STD):
        if not (np.isfinite(fps) and fps > 0):
            raise FilterError(f"fps={fps} must be positive")
        if min(ambiguous_heading_factor, ambiguous_joint_factor) < 1 or ambiguity_threshold < 0:
            raise FilterError("ambiguous factors must be >= 1 and ambiguity_threshold >= 0")
        q = np.broadcast_to(np.asarray(DEFAULT_ACCEL_STD**2 if q is None else q, float),
                            (N_ANGLES,))
        if not (np.isfinite(q).all() and (q >= 0).all()):
            raise FilterError("q (acceleration variances) must be finite and >= 0")
        self.fps = float(fps)
        self.dt = 1.0 / self.fps
        self.R = _as_covariance(R, "R")
        inflate = np.full(N_ANGLES, np.sqrt(ambiguous_joint_factor))
        inflate[0] = np.sqrt(ambiguous_heading_factor)
        # Scaling std per angle keeps correlations: R_amb = D R D with D = diag(sqrt(factor)).
        self.R_ambiguous = self.R * np.outer(inflate, inflate)
        self.ambiguity_threshold = ambiguity_threshold
        self.rate_std = rate_std
        dt, eye = self.dt, np.eye(N_ANGLES)
        self.F = np.block([[eye, dt * eye], [np.zeros_like(eye), eye]])
        self.H = np.hstack([eye, np.zeros_like(eye)])
        self.Q = np.block([[np.diag(q * dt**4 / 4), np.diag(q * dt**3 / 2)],
                           [np.diag(q * dt**3 / 2), np.diag(q * dt**2)]])
        self._kf: KalmanFilter | None = None

    def _new_filter(self, angles: np.ndarray, R: np.ndarray) -> KalmanFilter:
        """A filterpy filter started at ``angles`` (54,) deg with zero rates."""
        kf = KalmanFilter(dim_x=2 * N_ANGLES, dim_z=N_ANGLES)
        kf.F, kf.H, kf.Q, kf.R = self.F, self.H, self.Q, self.R
        kf.x = np.concatenate([angles, np.zeros(N_ANGLES)])[:, None]
        kf.P = np.zeros((2 * N_ANGLES, 2 * N_ANGLES))
        kf.P[:N_ANGLES, :N_ANGLES] = R
        kf.P[N_ANGLES:, N_ANGLES:] = np.eye(N_ANGLES) * self.rate_std**2
        return kf

    def _measure(self, raw55) -> tuple[np.ndarray, np.ndarray, bool]:
        """Check one raw pose; returns (angles (54,), R to use, ambiguous)."""
        raw = np.asarray(raw55, float)
        if raw.shape != (POSE_DIM,):
            raise FilterError(f"pose vector must have shape (55,), got {raw.shape}")
        if not np.isfinite(raw).all():
            bad = np.flatnonzero(~np.isfinite(raw)).tolist()
            raise FilterError(f"pose vector has non-finite entries at {bad}")
        angles, norm = pose_to_angles(raw)
        ambiguous = bool(norm < self.ambiguity_threshold)
        return angles, (self.R_ambiguous if ambiguous else self.R), ambiguous

    def _predict_update(self, kf: KalmanFilter, angles: np.ndarray, R: np.ndarray) -> None:
        """One filter step with the measurement unwrapped to within 180 deg of the prediction."""
        kf.predict()
        predicted = kf.x[:N_ANGLES, 0]
        z = predicted + wrap_deg(angles - predicted)
        kf.update(z[:, None], R=R)

    def reset(self) -> None:
        """Forget the track: the next :meth:`step` starts afresh."""
        self._kf = None

    def step(self, raw55) -> tuple[np.ndarray, bool]:
        """Filter one raw regressor output (55,) -> (filtered pose (55,), ambiguous flag)."""
        angles, R, ambiguous = self._measure(raw55)
        if self._kf is None:
            self._kf = self._new_filter(angles, R)
        else:
            self._predict_update(self._kf, angles, R)
            # Shifting angles by whole turns changes nothing (measurements are unwrapped against
            # the prediction) and keeps the state bounded on long clips.
            self._kf.x[:N_ANGLES] -= 360.0 * np.round(self._kf.x[:N_ANGLES] / 360.0)
        return angles_to_pose(self._kf.x[:N_ANGLES, 0]), ambiguous

    def rts_smooth(self, raws: Sequence | np.ndarray, window: int = 256,
                   lag: int = 64) -> np.ndarray:
        """Forward filter then Rauch-Tung-Striebel smoothing (filterpy) of a whole track.

        ``raws``: (T, 55) raw poses. Returns smoothed poses (T, 55). Does not touch the state
        used by :meth:`step`. filterpy's smoother keeps four (T, 108, 108) arrays (0.37 MB per
        frame), so long tracks are smoothed in windows of ``window`` frames, each run on
        ``lag`` further frames whose influence on the window has decayed (exact up to that
        decay; the tests bound it).
        """
        raws = np.asarray(raws, float)
        if raws.ndim != 2 or raws.shape[1] != POSE_DIM or len(raws) == 0:
            raise FilterError(f"rts_smooth needs poses of shape (T, 55), got {raws.shape}")
        if window < 1 or lag < 0:
            raise FilterError(f"window={window} must be >= 1 and lag={lag} >= 0")
        measurements = [self._measure(raw) for raw in raws]
        smoothed = np.empty((len(raws), N_ANGLES))
        kf = None
        for start in range(0, len(raws), window):
            stop = min(start + window + lag, len(raws))
            xs, ps = [], []
            for angles, R, _ in measurements[start:stop]:
                if kf is None:
                    kf = self._new_filter(angles, R)
                else:
                    self._predict_update(kf, angles, R)
                xs.append(kf.x.copy())
                ps.append(kf.P.copy())
                if len(xs) == window:
                    resume = (kf.x.copy(), kf.P.copy())  # the next window continues from here
            x_smooth, _, _, _ = kf.rts_smoother(np.array(xs), np.array(ps), Fs=[self.F] * len(xs),
                                                Qs=[self.Q] * len(xs))
            end = min(start + window, len(raws))
            smoothed[start:end] = x_smooth[: end - start, :N_ANGLES, 0]
            if stop > start + window:
                kf.x, kf.P = resume
        return angles_to_pose(smoothed)
