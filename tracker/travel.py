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
hypothesis implies (travel + ~180 for one walking backwards).
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
    centres, kappa, scale = _von_mises(float(travel_std_deg))
    delta = np.radians(np.asarray(heading_deg, dtype=np.float64) - travel_deg)
    # von Mises density relative to uniform: exp(kappa cos(d)) / I0(kappa), per offset bin
    per_bin = np.exp(kappa * (np.cos(delta[..., None] - centres) - 1.0)) / scale
    return per_bin @ FACING_TRAVEL_PRIOR


@functools.lru_cache(maxsize=8)
def _von_mises(travel_std_deg: float) -> tuple[np.ndarray, float, float]:
    """travel_likelihood's constants for one error std (degrees): the prior's bin centres
    (radians), kappa, and I0(kappa) / exp(kappa) (np.i0 costs ~0.1 ms a call: once here)."""
    centres = np.radians(np.arange(len(FACING_TRAVEL_PRIOR)) * _PRIOR_BIN_DEG)
    centres.flags.writeable = False
    std = np.radians(math.hypot(travel_std_deg, _PRIOR_BIN_DEG / math.sqrt(12.0)))
    kappa = 1.0 / std ** 2
    return centres, kappa, float(np.i0(kappa)) / math.exp(kappa)


def fuse_with_prior(poses: np.ndarray, travel_deg: float, raw_variance: float,
                    travel_std_deg: float = TRAVEL_STD_DEG):
    """Fuse the direction of travel into each hypothesis's heading without assuming the body
    faces it. The (facing - travel) offset is unknown: its posterior over FACING_TRAVEL_PRIOR's
    bins given a pose's heading (prior times N(heading - travel - offset; 0, raw_variance +
    travel_std_deg^2)) is moment-matched to one direction, travel + its circular mean offset,
    whose variance adds the offsets' spread to travel_std_deg^2; then fuse_heading. A hypothesis
    facing away from a backwards walker's travel is fused with travel + ~180, one facing across
    it barely at all (its offset is uncertain). poses (55,) or (K, 55); raw_variance deg^2.
    Returns (the poses with fused headings, same shape; fused variances deg^2: a float for one
    pose, else (K,))."""
    poses = np.asarray(poses, dtype=np.float64)
    heading = np.degrees(np.arctan2(poses[..., 1], poses[..., 0]))              # (...,)
    offsets = np.arange(len(FACING_TRAVEL_PRIOR)) * _PRIOR_BIN_DEG               # (B,)
    miss = wrap_deg(heading[..., None] - travel_deg - offsets)                   # (..., B)
    log_w = (np.log(FACING_TRAVEL_PRIOR)
             - 0.5 * miss ** 2 / (raw_variance + travel_std_deg ** 2))
    w = np.exp(log_w - log_w.max(axis=-1, keepdims=True))
    w /= w.sum(axis=-1, keepdims=True)
    mean = np.degrees(np.arctan2(w @ np.sin(np.radians(offsets)),
                                 w @ np.cos(np.radians(offsets))))              # (...,)
    spread = (w * wrap_deg(offsets - mean[..., None]) ** 2).sum(axis=-1)
    return fuse_heading(poses, travel_deg + mean, raw_variance,
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
