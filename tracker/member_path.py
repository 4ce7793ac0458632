"""Which body the limbs are, decided over a whole track (``--smooth``).

The limb networks give one of a silhouette's two bodies (their canonical member), and the
tracker takes it or its front/back flip (tracker.hypotheses.pick_member). Online it takes the
one whose heading is nearer the heading the front/back chain decided. In profile the two
headings (h and 180 - h) nearly meet, so a few degrees of heading error pick the wrong one, and
what differs between the two there is which leg is forward: the output's legs swap for a few
frames. Offline the whole track is known, and the choice can be made as the most probable
chain of members (regressor.hypothesis_path): each frame's evidence for a member is how near
its heading is to the smoothed heading (a Gaussian of MEMBER_HEADING_SD_DEG). Away from
profile the heading decides. In profile it cannot, and the step cost is the gait's: the
networks' member there is a rectified gait (the same leg ahead in most frames, the body's
configuration changing at the legs' crossings, docs/left_right.md), so the legs' continuity
follows the member through the crossings; but a walker's thigh difference changes sign at
every crossing and only there. So a step costs LEG_SIGN_COST nats when the chosen body's
thigh difference changes sign between two frames with no leg crossing between them, or keeps
it across one (:func:`leg_sign_unfolded`). With ``leg_sign_cost=0`` the step costs the
squared change of the 53 body angles over 2 MEMBER_STEP_VARIANCE instead (the legs'
continuity). The heading itself is not changed, nor is the online (filtered) output.

Only the ratio MEMBER_STEP_VARIANCE / MEMBER_HEADING_SD_DEG^2 matters; 0.44 was chosen on the
validation renders and videos (smoothed corr8 of the 28 renders 0.6356 -> 0.6407, of the 12
videos 0.618 -> 0.626). The measurements, the other ratios tried and the held-out figures:
docs/accuracy.md, "2026-12-04 (stop 42)". The leg-sign cost's figures: docs/left_right.md.
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.signal import argrelmin

from regressor.angles import wrap_deg
from regressor.hypothesis_path import most_probable_path
from sequences.pose_vector import front_back_flip, heading_deg, pose_vector_names

MEMBER_HEADING_SD_DEG = 30.0        # the evidence: how near each member's heading is
MEMBER_STEP_VARIANCE = 400.0        # deg^2: the 53 angles' summed squared step per frame
LEG_SIGN_COST = 1.0                 # nats: one heading evidence's 1.4 SD; 3 unfolded less
CROSSING_ORDER = 3                  # frames: a crossing is |g|'s minimum within this many
CROSSING_DEPTH = 0.5                # ... and below this fraction of |g|'s median
_LEFT_THIGH, _RIGHT_THIGH = (pose_vector_names().index(n) for n in ("LeftUpLeg_x",
                                                                      "RightUpLeg_x"))


def leg_sign_unfolded(limbs) -> np.ndarray:
    """(T,) the sign of each frame's thigh difference g = LeftUpLeg_x - RightUpLeg_x of limbs
    (T, 55), times -1 for each leg crossing before it: constant along a walker's true body.

    A crossing is a local minimum of |g| (smoothed over 3 frames) within CROSSING_ORDER frames
    and below CROSSING_DEPTH x its median, placed between the minimum's frame and its
    neighbour of smaller |g| (where g's zero lies). The flip's g is -g, so its value is minus
    the member's."""
    g = np.asarray(limbs, dtype=np.float64)[:, _LEFT_THIGH] - \
        np.asarray(limbs, dtype=np.float64)[:, _RIGHT_THIGH]
    T = len(g)
    if T < 3:
        return np.sign(g)
    a = uniform_filter1d(np.abs(g), 3)
    minima = argrelmin(a, order=CROSSING_ORDER)[0]
    minima = minima[a[minima] < CROSSING_DEPTH * np.median(a)]
    nxt, prv = np.abs(g[np.minimum(minima + 1, T - 1)]), np.abs(g[np.maximum(minima - 1, 0)])
    after = (minima + 1 < T) & ((minima == 0) | (nxt < prv))
    crossing = np.zeros(T, dtype=np.int64)              # crossing[t]: between t-1 and t
    crossing[minima + after] = 1
    return np.sign(g) * np.where(np.cumsum(crossing) % 2 == 0, 1.0, -1.0)


def members_over_time(limbs, headings_deg, frame_rate_ratio: float = 1.0,
                      heading_sd_deg: float = MEMBER_HEADING_SD_DEG,
                      step_variance: float = MEMBER_STEP_VARIANCE,
                      leg_sign_cost: float = LEG_SIGN_COST) -> np.ndarray:
    """Of each frame's canonical pose and its front/back flip, the ones on the most probable
    chain (module docstring).

    limbs: (T, 55) canonical poses ((cos, sin) of the heading, 53 body angles in degrees) in
    time order; headings_deg: (T,) the decided (smoothed) heading, degrees; frame_rate_ratio:
    the chain's (tracker.hypotheses.FrontBackTracker.frame_rate_ratio, 0.25 at 120 fps for
    the 30 fps the settings were chosen at): each frame's heading evidence is multiplied by
    it, so a second of video weighs the same at any rate. The steps are not: a switch of
    member is one jump whatever the rate. leg_sign_cost: nats per step against the gait's
    sign rule (module docstring); 0: the 53 angles' continuity over step_variance instead.
    Returns (T, 55): each frame's chosen member, whole."""
    limbs = np.asarray(limbs, dtype=np.float64)
    headings = np.asarray(headings_deg, dtype=np.float64)
    if limbs.ndim != 2 or limbs.shape[1] != 55 or headings.shape != (len(limbs),):
        raise ValueError(f"limbs must be (T, 55) and headings (T,), got {limbs.shape} and "
                         f"{headings.shape}")
    if len(limbs) == 0:
        return limbs.copy()
    pair = np.stack([limbs, front_back_flip(limbs)], axis=1)                 # (T, 2, 55)
    off = wrap_deg(heading_deg(pair.reshape(-1, 55)).reshape(-1, 2) - headings[:, None])
    log_weight = -frame_rate_ratio * off ** 2 / (2.0 * heading_sd_deg ** 2)
    if leg_sign_cost > 0:
        # The unfolded sign of the member and of its flip (+-1); a bad step changes it by 2,
        # so a Gaussian step of variance 2 / cost charges it `cost` nats.
        unfolded = leg_sign_unfolded(limbs)
        signs = np.stack([unfolded, -unfolded], axis=1)[:, :, None]          # (T, 2, 1)
        path = most_probable_path(signs, log_weight, 2.0 / leg_sign_cost)
    else:
        path = most_probable_path(pair[:, :, 2:], log_weight, step_variance, angles_deg=True)
    return pair[np.arange(len(pair)), path]
