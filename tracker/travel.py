"""Direction of travel from the image: evidence on the silhouette's front/back ambiguity.

A silhouette seen from the front looks much like one seen from the back, so on ambiguous frames
the regressor's heading may be the right one or 180 degrees off. A walking person moves the
way they face; the image tells which way they move: sideways by the centroid's motion, towards
or away from the camera by the silhouette growing or shrinking. For a pinhole camera with focal
length f pixels and a person at image column u (principal point cx), height h pixels:

    lateral velocity  dX/dt = Z/f * (du/dt - (u - cx) * dlog(h)/dt)
    approach velocity -dZ/dt = Z * dlog(h)/dt

whose direction, turned to the line of sight (atan((u - cx) / f)), is the heading the person
would have if walking forwards (0 = towards the camera, +90 = towards image right). Z cancels,
so no body size is assumed; f comes from an assumed field of view, which only stretches the
angle, not which half-plane it is in, and a half-plane is all the front/back choice needs.

Only while the person moves faster than ``min_speed`` (body heights per second). It is soft
evidence for the front/back hypotheses (tracker/hypotheses.py), never an override: people do
not always face where they go. travel_likelihood uses the motion capture's distribution of
(facing - travel) (FACING_TRAVEL_PRIOR: forwards mostly, backwards and sideways too), and
fuse_with_prior fuses the travel direction into a hypothesis's heading with the offset that
hypothesis implies (travel + ~180 for one walking backwards). A track learns its own offset
over time (tracker.hypotheses, offset_memory): offset_likelihoods gives the travel's
likelihood per bin, offset_transition how the offset moves between bins from frame to frame
(FACING_TRAVEL_STEPS, from the motion capture), and fuse_with_prior takes the track's belief
as its prior.
"""
from __future__ import annotations

import functools
import math
from collections import deque

import numpy as np

from regressor.angles import wrap_deg

from .video import focal_length_px

DEFAULT_WINDOW = 15             # frames fitted (0.5 s at 30 fps): smooths the gait's bobbing
DEFAULT_MIN_SPEED = 0.15        # body heights per second (a slow walk is ~0.6)
TRAVEL_STD_DEG = 25.0           # error of the travel direction as a heading, see fuse_heading

#: P(facing - direction of travel falls in a 30-degree bin), bins centred on 0, 30, ..., 180,
#: ..., 330 (= -30) degrees: every frame where the root moves faster than DEFAULT_MIN_SPEED
#: (travel fitted over DEFAULT_WINDOW frames at 30 fps, as TravelDirection does) of the 92
#: training trials of ../shared/data/cmu (17,800 frames: walks, runs, forward, backward 06_07
#: and sideways 06_09 dribbling, dance; the held-out trials, sequences.dataset.HELD_OUT_TRIALS,
#: among them the backward and sideways dribbles 06_06 and 06_08, left out). Measured by
#: scripts/learn_hypothesis_priors.py. Forwards (within 45 degrees) 0.70, backwards (within 15
#: of 180) 0.076, sideways ~0.03 a bin. (Before 2026-12-04 it was learned on all 99 trials,
#: the held-out ones too: [0.4415, 0.1530, 0.0580, 0.0226, 0.0130, 0.0283, 0.0791, 0.0296,
#: 0.0203, 0.0257, 0.0308, 0.0981].)
FACING_TRAVEL_PRIOR = np.array([0.4412, 0.1558, 0.0593, 0.0224, 0.0124, 0.0280, 0.0764, 0.0299,
                                0.0204, 0.0229, 0.0307, 0.1006])
_PRIOR_BIN_DEG = 360.0 / len(FACING_TRAVEL_PRIOR)
#: How a body's (facing - travel) moves between FACING_TRAVEL_PRIOR's bins from one 30 fps frame
#: (FACING_TRAVEL_FPS) to the next while it keeps moving: row 0 the probability of one bin down
#: (towards -30 degrees), row 1 one bin up, from each bin; it stays in its bin otherwise (a jump
#: of two bins or more in a frame: 2 of the 17,427 pairs, not modelled). The offset persists: a
#: body walking backwards keeps doing so (from the 180 bin it leaves 4 % of frames), so the
#: travel evidence of one frame is not independent of the last's. Measured by
#: scripts/learn_hypothesis_priors.py (tracker.offline.hypothesis_priors.facing_travel_steps) on
#: the 92 training trials of ../shared/data/cmu (the held-out ones,
#: sequences.dataset.HELD_OUT_TRIALS, left out; 17,427 frame pairs).
FACING_TRAVEL_STEPS = np.array([
    [0.0173, 0.0528, 0.0570, 0.0712, 0.0948, 0.0418, 0.0192, 0.0747, 0.0774, 0.0630, 0.0705,
     0.0295],
    [0.0206, 0.0249, 0.0309, 0.0475, 0.0900, 0.0543, 0.0231, 0.0393, 0.0487, 0.0680, 0.0648,
     0.0653]])
FACING_TRAVEL_FPS = 30.0        # the frame rate FACING_TRAVEL_STEPS are per frame of


def travel_heading(u_px: np.ndarray, height_px: np.ndarray, fps: float, frame_width: int,
                   focal_px: float | None = None) -> tuple[float, float]:
    """Heading of travel (degrees, pose-vector convention relative to the line of sight) and
    speed (body heights per second) from the last n frames' centroid columns u_px (n,) and
    silhouette heights height_px (n,), by least-squares slopes over the window. focal_px: the
    camera's focal length in pixels (None: tracker.video.focal_length_px(frame_width))."""
    u = np.asarray(u_px, dtype=np.float64)
    log_h = np.log(np.asarray(height_px, dtype=np.float64))
    t = (np.arange(len(u)) - (len(u) - 1) / 2.0) / fps
    denom = float(t @ t)
    du, dlogh = float(t @ (u - u.mean())) / denom, float(t @ (log_h - log_h.mean())) / denom
    f = focal_length_px(frame_width) if focal_px is None else focal_px
    offset = u[-1] - 0.5 * (frame_width - 1)
    lateral = du - offset * dlogh                     # x Z/f
    approach = f * dlogh                              # x Z/f
    heading = math.degrees(math.atan2(lateral, approach) + math.atan2(offset, f))
    speed = math.hypot(lateral, approach) / height_px[-1]     # heights per second
    return float(wrap_deg(heading)), speed


class TravelDirection:
    """Per-track rolling estimate of the direction of travel (see the module docstring).

    fps: video frame rate; frame_width: pixels; window: frames fitted; min_speed: body heights
    per second below which there is no estimate; focal_px: as travel_heading.
    """

    def __init__(self, fps: float, frame_width: int, window: int = DEFAULT_WINDOW,
                 min_speed: float = DEFAULT_MIN_SPEED, focal_px: float | None = None):
        self.fps, self.frame_width = float(fps), int(frame_width)
        self.focal_px = focal_length_px(frame_width) if focal_px is None else focal_px
        self.min_speed = min_speed
        self._u: deque = deque(maxlen=window)
        self._h: deque = deque(maxlen=window)

    def push(self, centroid_x_px: float, height_px: float) -> float | None:
        """Add this frame's centroid column and silhouette height (pixels); returns the heading
        of travel in degrees, or None while the window is filling or the person is slow."""
        self._u.append(float(centroid_x_px))
        self._h.append(max(float(height_px), 1.0))
        if len(self._u) < self._u.maxlen:
            return None
        heading, speed = travel_heading(np.array(self._u), np.array(self._h), self.fps,
                                        self.frame_width, self.focal_px)
        return heading if speed >= self.min_speed else None


def travel_likelihood(heading_deg, travel_deg: float,
                      travel_std_deg: float = TRAVEL_STD_DEG) -> np.ndarray:
    """p(the image shows travel in direction travel_deg | the body's heading is heading_deg),
    relative to a uniform density (1 = no information): the mocap distribution of (facing -
    travel), FACING_TRAVEL_PRIOR, seen through the image estimate's error (a von Mises of std
    travel_std_deg, widened by the bins' own width). heading_deg: any shape; degrees, the pose
    vector's convention (as travel_heading). Soft: walking backwards is 0.076 / 0.44 as likely
    as forwards per observation, never impossible."""
    return offset_likelihoods(heading_deg, travel_deg, travel_std_deg) @ FACING_TRAVEL_PRIOR


def offset_likelihoods(heading_deg, travel_deg: float,
                       travel_std_deg: float = TRAVEL_STD_DEG) -> np.ndarray:
    """p(the image shows travel in direction travel_deg | heading heading_deg, (facing -
    travel) in FACING_TRAVEL_PRIOR's bin b) relative to a uniform density: (..., n_bins) for
    heading_deg of any shape (degrees), a von Mises of std travel_std_deg widened by the bins'
    own width (see travel_likelihood, which weighs these by the prior)."""
    centres, kappa, scale = _von_mises(float(travel_std_deg))
    delta = np.radians(np.asarray(heading_deg, dtype=np.float64) - travel_deg)
    # von Mises density relative to uniform: exp(kappa cos(d)) / I0(kappa)
    return np.exp(kappa * (np.cos(delta[..., None] - centres) - 1.0)) / scale


@functools.lru_cache(maxsize=8)
def offset_transition(frame_share: float = 1.0) -> np.ndarray:
    """The (facing - travel) bins' transition matrix (n_bins, n_bins), rows summing to 1, over
    frame_share of a FACING_TRAVEL_FPS frame (FACING_TRAVEL_STEPS; 0.25 for a 120 fps frame),
    while the body moves (the steps were counted on moving frames only): the
    one-frame matrix's power for whole frames, the share of a frame's steps for the rest (for
    a share below 1 the chance of a step is that share of a frame's)."""
    if frame_share < 0:
        raise ValueError(f"frame share must be >= 0, got {frame_share}")
    n = len(FACING_TRAVEL_PRIOR)
    bins = np.arange(n)
    step = np.eye(n) * (1.0 - FACING_TRAVEL_STEPS.sum(axis=0))
    step[bins, (bins - 1) % n] += FACING_TRAVEL_STEPS[0]
    step[bins, (bins + 1) % n] += FACING_TRAVEL_STEPS[1]
    whole, part = divmod(float(frame_share), 1.0)
    out = np.linalg.matrix_power(step, int(whole)) @ ((1.0 - part) * np.eye(n) + part * step)
    out.flags.writeable = False
    return out


@functools.lru_cache(maxsize=8)
def _von_mises(travel_std_deg: float) -> tuple[np.ndarray, float, float]:
    """travel_likelihood's constants for one error std (degrees): the prior's bin centres
    (radians), kappa, and I0(kappa) / exp(kappa) (np.i0 costs ~0.1 ms a call: once here)."""
    centres = np.radians(np.arange(len(FACING_TRAVEL_PRIOR)) * _PRIOR_BIN_DEG)
    centres.flags.writeable = False
    std = np.radians(math.hypot(travel_std_deg, _PRIOR_BIN_DEG / math.sqrt(12.0)))
    kappa = 1.0 / std ** 2
    return centres, kappa, float(np.i0(kappa)) / math.exp(kappa)


def fuse_with_prior(raw: np.ndarray, travel_deg: float, raw_variance: float,
                    travel_std_deg: float = TRAVEL_STD_DEG,
                    prior: np.ndarray = FACING_TRAVEL_PRIOR) -> tuple[np.ndarray, float]:
    """Fuse the direction of travel into one hypothesis's heading without assuming the body
    faces it. The (facing - travel) offset is unknown: its posterior over FACING_TRAVEL_PRIOR's
    bins given this heading (prior times N(heading - travel - offset; 0, raw_variance +
    travel_std_deg^2)) is moment-matched to one direction, travel + its circular mean offset,
    whose variance adds the offsets' spread to travel_std_deg^2; then fuse_heading. A hypothesis
    facing away from a backwards walker's travel is fused with travel + ~180, one facing across
    it barely at all (its offset is uncertain). raw (55,); raw_variance deg^2. Returns (pose
    (55,), fused variance deg^2). prior: the offset's probabilities over the bins
    (n_bins,), the population's by default; a track's own belief (tracker.hypotheses) knows
    more. fuse_with_priors does many at once."""
    fused, variance = fuse_with_priors(np.asarray(raw)[None], travel_deg, raw_variance,
                                       np.asarray(prior)[None], travel_std_deg)
    return fused[0, 0], float(variance[0, 0])


def fuse_with_priors(poses: np.ndarray, travel_deg: float, raw_variance: float,
                     priors: np.ndarray, travel_std_deg: float = TRAVEL_STD_DEG
                     ) -> tuple[np.ndarray, np.ndarray]:
    """fuse_with_prior for every pose under every prior: poses (K, 55), priors (M, n_bins);
    returns the fused poses (M, K, 55) and their fused heading variances (M, K) deg^2."""
    poses = np.asarray(poses, dtype=np.float64)
    heading = np.degrees(np.arctan2(poses[:, 1], poses[:, 0]))                  # (K,)
    offsets = np.arange(len(FACING_TRAVEL_PRIOR)) * _PRIOR_BIN_DEG               # (B,)
    miss = wrap_deg(heading[:, None] - travel_deg - offsets)                     # (K, B)
    log_w = (np.log(np.maximum(priors, 1e-12))[:, None, :]
             - 0.5 * miss[None] ** 2 / (raw_variance + travel_std_deg ** 2))     # (M, K, B)
    w = np.exp(log_w - log_w.max(axis=-1, keepdims=True))
    w /= w.sum(axis=-1, keepdims=True)
    mean = np.degrees(np.arctan2(w @ np.sin(np.radians(offsets)),
                                 w @ np.cos(np.radians(offsets))))              # (M, K)
    spread = (w * wrap_deg(offsets - mean[..., None]) ** 2).sum(axis=-1)
    return fuse_heading(np.broadcast_to(poses, mean.shape + poses.shape[1:]),
                        travel_deg + mean, raw_variance,
                        np.sqrt(travel_std_deg ** 2 + spread))


def fuse_heading(raw: np.ndarray, travel_deg, raw_variance: float,
                 travel_std_deg=TRAVEL_STD_DEG) -> tuple[np.ndarray, np.ndarray | float]:
    """Combine the regressor's heading (raw (..., 55), front/back already settled, variance
    raw_variance deg^2) with the direction of travel (degrees, std travel_std_deg; each a
    float or of raw's leading shape) by inverse variance weighting on the circle: the same as
    two Kalman updates with independent errors. Returns (raw with the fused heading, same
    (cos, sin) norm; fused variance deg^2, a float for one pose). travel_std_deg: measured on
    the sample walk's true boxes, the travel direction's error has median 13.5 and 90th
    percentile 38 degrees (walking forwards)."""
    out = np.array(raw, dtype=np.float64, copy=True)
    norm = np.hypot(out[..., 0], out[..., 1])
    heading = np.degrees(np.arctan2(out[..., 1], out[..., 0]))
    w_raw, w_travel = 1.0 / raw_variance, 1.0 / np.asarray(travel_std_deg, np.float64) ** 2
    delta = wrap_deg(np.asarray(travel_deg, np.float64) - heading)
    fused = np.radians(heading + delta * w_travel / (w_raw + w_travel))
    out[..., 0], out[..., 1] = norm * np.cos(fused), norm * np.sin(fused)
    variance = 1.0 / (w_raw + w_travel)
    return out, float(variance) if np.ndim(variance) == 0 else variance
