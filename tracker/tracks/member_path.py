"""Which body the limbs are, decided over a whole track (``--smooth``): online the member whose
heading is nearer the chain's (hypotheses.pick_member), but in profile the headings nearly meet;
offline the most probable chain of members (regressor.hypothesis_path; docs/tuning.md)."""
from __future__ import annotations

import numpy as np

from regressor.angles import wrap_deg
from regressor.hypothesis_path import most_probable_path
from sequences.pose_vector import front_back_flip, heading_deg

MEMBER_HEADING_SD_DEG = 30.0        # the evidence: how near each member's heading is
MEMBER_STEP_VARIANCE = 400.0        # deg^2: the 53 angles' summed squared step per frame


def members_over_time(limbs, headings_deg, frame_rate_ratio: float = 1.0,
                      step_variance: float = MEMBER_STEP_VARIANCE) -> np.ndarray:
    """Of each frame's canonical pose and its flip (limbs (T, 55), in time order), the ones on
    the most probable chain (T, 55): a member's log evidence is a Gaussian's (sd
    MEMBER_HEADING_SD_DEG) of its heading's distance to headings_deg (T,) times frame_rate_ratio;
    each step costs the squared change of the 53 body angles (degrees) over 2 step_variance."""
    limbs = np.asarray(limbs, dtype=np.float64)
    headings = np.asarray(headings_deg, dtype=np.float64)
    if limbs.ndim != 2 or limbs.shape[1] != 55 or headings.shape != (len(limbs),):
        raise ValueError(f"limbs must be (T, 55) and headings (T,), got {limbs.shape} and "
                         f"{headings.shape}")
    if len(limbs) == 0:
        return limbs.copy()
    pair = np.stack([limbs, front_back_flip(limbs)], axis=1)                 # (T, 2, 55)
    off = wrap_deg(heading_deg(pair.reshape(-1, 55)).reshape(-1, 2) - headings[:, None])
    log_weight = -frame_rate_ratio * off ** 2 / (2.0 * MEMBER_HEADING_SD_DEG ** 2)
    path = most_probable_path(pair[:, :, 2:], log_weight, step_variance, angles_deg=True)
    return pair[np.arange(len(pair)), path]
