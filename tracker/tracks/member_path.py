"""Which body the limbs are, decided over a whole track (``--smooth``).

Online the tracker takes the limbs' canonical member or its flip, whichever heading is nearer
the chain's (hypotheses.pick_member); in profile the headings nearly meet and what differs is
which leg is forward. Offline the choice is the most probable chain of members
(regressor.hypothesis_path): a frame's evidence for a member is a Gaussian (MEMBER_HEADING_SD_DEG)
of its heading's distance to the smoothed heading, each step costs the squared change of the 53
body angles over 2 MEMBER_STEP_VARIANCE. Only their ratio matters: docs/tuning.md.
"""
from __future__ import annotations

import numpy as np

from regressor.angles import wrap_deg
from regressor.hypothesis_path import most_probable_path
from sequences.pose_vector import front_back_flip, heading_deg

MEMBER_HEADING_SD_DEG = 30.0        # the evidence: how near each member's heading is
MEMBER_STEP_VARIANCE = 400.0        # deg^2: the 53 angles' summed squared step per frame


def members_over_time(limbs, headings_deg, frame_rate_ratio: float = 1.0,
                      heading_sd_deg: float = MEMBER_HEADING_SD_DEG,
                      step_variance: float = MEMBER_STEP_VARIANCE) -> np.ndarray:
    """Of each frame's canonical pose and its front/back flip, the ones on the most probable
    chain (module docstring).

    limbs: (T, 55) canonical poses ((cos, sin) of the heading, 53 body angles in degrees) in
    time order; headings_deg: (T,) the decided (smoothed) heading, degrees; frame_rate_ratio:
    the chain's (tracker.tracks.hypotheses.FrontBackTracker.frame_rate_ratio, 0.25 at 120 fps for
    the 30 fps the settings were chosen at): each frame's heading evidence is multiplied by
    it, so a second of video weighs the same at any rate. The steps are not: a switch of
    member is one jump whatever the rate. Returns (T, 55): each frame's chosen member, whole."""
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
    path = most_probable_path(pair[:, :, 2:], log_weight, step_variance, angles_deg=True)
    return pair[np.arange(len(pair)), path]
