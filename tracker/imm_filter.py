"""An interacting-multiple-model (IMM) pose filter: the heading is filtered by several motion
models at once, mixed by how well each has explained the measurements.

Why: PoseKalmanFilter's heading is a constant-velocity model with small process noise (the
tracker's, tracker.pipeline.HEADING_Q_SCALE), so a turn's rate it has learned persists after
the turn stops and the estimate runs on past it. A single setting trades steady turns (which
want the rate kept) against stops (which want it forgotten). The IMM (Blom and Bar-Shalom,
IEEE Trans. Automatic Control 1988; Bar-Shalom, Li and Kirubarajan, "Estimation with
Applications to Tracking and Navigation", 2001) keeps one filter per model and a Markov chain
over which model is in force:

    mixing      c_j = sum_i pi_ij mu_i,   mu_i|j = pi_ij mu_i / c_j
                x0_j = sum_i mu_i|j x_i,  P0_j = sum_i mu_i|j (P_i + (x_i - x0_j)(x_i - x0_j)')
    per model   predict x0_j, P0_j with model j's F_j, Q_j; update with the measurement
    weights     mu_j ~ c_j N(y_j; 0, S_j)
    output      x = sum_j mu_j x_j

Models differ only in the heading's dynamics (its process noise and how fast its rate is
forgotten, exp(-dt / tau) per frame); the 53 joint angles move as PoseKalmanFilter's in every
model. The state layout, measurement handling (unwrapping, ambiguity, a per-frame heading
variance) and interface (step, log_likelihoods, copy, reset) are PoseKalmanFilter's, so the
front/back chain (tracker/hypotheses.py) runs it unchanged; rts_smooth stays
PoseKalmanFilter's constant-velocity smoother with the filter's own q (the first model's when,
as in the tracker, that model is HeadingModel()).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from regressor.angles import N_ANGLES, angles_to_pose, wrap_deg
from tracker.filtering import (FilterError, PoseKalmanFilter, initial_state,
                               innovation_factor, innovation_log_likelihood, kalman_update)


@dataclass(frozen=True)
class HeadingModel:
    """One heading motion model. q_scale: multiplies the heading's acceleration variance;
    rate_time: seconds over which the heading's rate is forgotten (None: kept, constant
    velocity)."""

    q_scale: float = 1.0
    rate_time: float | None = None


#: Constant velocity, and a model that forgets the heading's rate over 0.3 s: the tracker's
#: choice (tracker.pipeline.HEADING_MODELS gives the measurements).
TURN_AND_STOP = (HeadingModel(), HeadingModel(1.0, 0.3))
DEFAULT_SWITCH = 0.01       # per frame at 30 fps: a model lasts about 3 s


def _transition(n_models: int, switch: float) -> np.ndarray:
    """Markov transition matrix (M, M): stay with probability 1 - switch, else move to one of
    the other models evenly."""
    if n_models == 1:
        return np.ones((1, 1))
    pi = np.full((n_models, n_models), switch / (n_models - 1))
    np.fill_diagonal(pi, 1.0 - switch)
    return pi


class IMMPoseFilter(PoseKalmanFilter):
    """PoseKalmanFilter whose heading follows several models mixed as an IMM (module docstring).

    models: the heading models (the first is also the smoother's); switch: probability per
    frame at ``switch_fps`` of leaving the model in force (rescaled to the filter's fps so a
    model lasts as many seconds at any frame rate). Other arguments as PoseKalmanFilter's.
    """

    def __init__(self, fps: float, R=None, q=None, *,
                 models: tuple[HeadingModel, ...] = TURN_AND_STOP,
                 switch: float = DEFAULT_SWITCH, switch_fps: float = 30.0, **kwargs):
        super().__init__(fps, R=R, q=q, **kwargs)
        if not models:
            raise FilterError("IMMPoseFilter needs at least one heading model")
        if not (0.0 < switch < 1.0 and np.isfinite(switch_fps) and switch_fps > 0):
            raise FilterError(f"switch={switch} must lie in (0, 1) and switch_fps > 0")
        dt = self.dt
        self.models = tuple(models)
        self.rate_factors, self._q_corrections = [], []
        self._heading_block = np.ix_([0, N_ANGLES], [0, N_ANGLES])
        for model in self.models:
            if not (np.isfinite(model.q_scale) and model.q_scale > 0):
                raise FilterError(f"heading model q_scale={model.q_scale} must be > 0")
            a = 1.0
            if model.rate_time is not None:
                if not (np.isfinite(model.rate_time) and model.rate_time > 0):
                    raise FilterError(f"heading model rate_time={model.rate_time} must be a "
                                      "positive number of seconds")
                a = float(np.exp(-dt / model.rate_time))
            self.rate_factors.append(a)
            # What the plain prediction's Q becomes, scaled as in _predict_model, against model
            # j's Q, on the heading's (angle, rate) entries: the only ones that differ.
            plain, scale = self.cv.q[0], np.array([1.0, a])
            block = np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])
            self._q_corrections.append((plain * model.q_scale - plain * np.outer(scale, scale))
                                       * block)
        # Probability of staying per frame at this fps: (1 - switch) per 1/switch_fps seconds.
        stay = (1.0 - switch) ** (switch_fps / self.fps)
        self.transition = _transition(len(self.models), 1.0 - stay)
        self._xs: np.ndarray | None = None     # (M, 108) per-model states
        self._Ps: np.ndarray | None = None     # (M, 108, 108)
        self._mu: np.ndarray | None = None     # (M,) model probabilities
        self._imm_predicted: tuple | None = None

    @property
    def model_probabilities(self) -> np.ndarray | None:
        """(M,) probability of each heading model after the last step; None before it."""
        return None if self._mu is None else self._mu.copy()

    def reset(self) -> None:
        super().reset()
        self._xs = self._Ps = self._mu = None
        self._imm_predicted = None

    def _predict_model(self, j: int, x: np.ndarray, P: np.ndarray):
        """x (108,), P (108, 108) one frame ahead under model j. Its F is the constant-velocity
        F with the heading's rate row scaled by a_j (F_j = D F, D = diag(1, .., a_j, .., 1)), so
        F_j P F_j' = D (F P F') D: the plain prediction, its heading-rate row and column scaled,
        and the heading's 2 x 2 block of Q replaced by model j's."""
        n, a = N_ANGLES, self.rate_factors[j]
        x, out = self.cv._predict(x, P)
        if a != 1.0:
            x[n] *= a
            out[n, :] *= a
            out[:, n] *= a
        out[self._heading_block] += self._q_corrections[j]
        return x, out

    def _imm_prediction(self):
        """(c (M,), predictions [(x_pred, P_pred)] per model, factor caches per model), once per
        frame."""
        if self._imm_predicted is None:
            n = N_ANGLES
            c = self._mu @ self.transition
            weights = (self.transition * self._mu[:, None]) / np.maximum(c, 1e-300)[None, :]
            predictions = []
            for j in range(len(self.models)):
                xs = self._xs.copy()
                # Angles of other models' states are unwrapped against model j's before mixing.
                xs[:, :n] = xs[j, :n] + wrap_deg(xs[:, :n] - xs[j, :n])
                x0 = weights[:, j] @ xs
                d = xs - x0
                P0 = (d.T * weights[:, j]) @ d
                for i, w in enumerate(weights[:, j]):
                    P0 += w * self._Ps[i]
                predictions.append(self._predict_model(j, x0, P0))
            self._imm_predicted = (c, predictions, [{} for _ in self.models])
        return self._imm_predicted

    def _model_factor(self, j: int, R, ambiguous: bool, variance):
        """Cholesky factor and log-determinant of model j's innovation covariance, cached."""
        _, predictions, caches = self._imm_prediction()
        return innovation_factor(predictions[j][1], caches[j], R, ambiguous, variance)

    def log_likelihoods(self, raws, heading_variance=None) -> np.ndarray:
        """As PoseKalmanFilter.log_likelihoods, under the IMM's predictive mixture:
        log sum_j c_j N(z_k - H x_pred_j; 0, S_j)."""
        raws = np.asarray(raws, float)
        if self._xs is None:
            return np.zeros(len(raws))
        c, predictions, _ = self._imm_prediction()
        variances = np.full(len(raws), np.nan) if heading_variance is None else heading_variance
        out = np.empty(len(raws))
        for k, (raw, variance) in enumerate(zip(raws, variances)):
            angles, R, ambiguous = self._measure(raw, variance)
            terms = np.empty(len(self.models))
            for j, (x_pred, _) in enumerate(predictions):
                terms[j] = np.log(max(c[j], 1e-300)) + innovation_log_likelihood(
                    *self._model_factor(j, R, ambiguous, variance), angles, x_pred)
            top = terms.max()
            out[k] = top + np.log(np.exp(terms - top).sum())
        return out

    def step(self, raw55, heading_variance: float | None = None) -> tuple[np.ndarray, bool]:
        """Filter one raw pose (55,) -> (filtered pose (55,), ambiguous flag), as
        PoseKalmanFilter.step; the output is the model-probability-weighted state."""
        angles, R, ambiguous = self._measure(raw55, heading_variance)
        n, M = N_ANGLES, len(self.models)
        if self._xs is None:
            x, P = initial_state(angles, R, self.rate_std)
            self._xs, self._Ps = np.repeat(x[None], M, 0), np.repeat(P[None], M, 0)
            self._mu = np.full(M, 1.0 / M)
        else:
            c, predictions, _ = self._imm_prediction()
            xs, Ps, logs = np.empty_like(self._xs), np.empty_like(self._Ps), np.empty(M)
            for j, (x_pred, P_pred) in enumerate(predictions):
                L, logdet = self._model_factor(j, R, ambiguous, heading_variance)
                xs[j], Ps[j], w = kalman_update(x_pred, P_pred, L, angles)
                logs[j] = np.log(max(c[j], 1e-300)) - 0.5 * (w @ w + logdet)
            mu = np.exp(logs - logs.max())
            self._xs, self._Ps, self._mu = xs, Ps, mu / mu.sum()
        self._imm_predicted = None
        x = self._xs.copy()
        x[:, :n] = x[0, :n] + wrap_deg(x[:, :n] - x[0, :n])
        return angles_to_pose((self._mu @ x)[:n]), ambiguous
