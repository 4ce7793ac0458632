"""Which body the limbs are, decided over a whole track (``--smooth``).

The limb networks give one of a silhouette's two bodies (their canonical member), and the
tracker takes it or its front/back flip (tracker.hypotheses.pick_member). Online it takes the
one whose heading is nearer the heading the front/back chain decided. In profile the two
headings (h and 180 - h) nearly meet, so a few degrees of heading error pick the wrong one, and
what differs between the two there is which leg is forward: the output's legs swap for a few
frames. Offline the whole track is known, and the choice can be made as the most probable
chain of members (regressor.hypothesis_path): each frame's evidence for a member is how near
its heading is to the smoothed heading (a Gaussian of MEMBER_HEADING_SD_DEG), and each step
from one frame's member to the next costs the squared change of the 53 body angles over
2 MEMBER_STEP_VARIANCE. Away from profile the heading decides; in profile, where it cannot,
the legs' continuity does. The heading itself is not changed.

Measured (2026-12-04, the shipped model, smoothed output; chosen on validation, one-off
drivers /work/tmp/s42/replay_lp.py and vids.py): on the 28 validation renders (the chain
replayed as ``track`` builds it) corr8 0.6356 -> 0.6407, err53 6.811 -> 6.790, heading
unchanged (23.89); on the 12 validation videos through ``track`` corr8 0.618 -> 0.626, err53
7.013 -> 6.980 (02_02 spiral 0.744 -> 0.800, 05_02 spiral 0.044 -> 0.080; no video lower).
Only the ratio MEMBER_STEP_VARIANCE / MEMBER_HEADING_SD_DEG^2 matters: 0.11 / 0.44 / 1.8 /
7.1 gave renders 0.6403 / 0.6407 / 0.6424 / 0.6351 and videos - / 0.626 / 0.623 / 0.617.
The same recursion online (each frame's member the best of a forward pass, no look-ahead)
gains nothing (filtered corr8 0.5845 -> 0.5840 on the renders), so online stays as it was.
"""
from __future__ import annotations

import numpy as np

from regressor.angles import wrap_deg
from regressor.hypothesis_path import most_probable_path
from sequences.pose_vector import front_back_flip, heading_deg

MEMBER_HEADING_SD_DEG = 30.0        # the evidence: how near each member's heading is
MEMBER_STEP_VARIANCE = 400.0        # deg^2: the 53 angles' summed squared step per frame


def members_over_time(limbs, headings_deg, evidence_weight: float = 1.0,
                      heading_sd_deg: float = MEMBER_HEADING_SD_DEG,
                      step_variance: float = MEMBER_STEP_VARIANCE) -> np.ndarray:
    """Of each frame's canonical pose and its front/back flip, the ones on the most probable
    chain (module docstring).

    limbs: (T, 55) canonical poses ((cos, sin) of the heading, 53 body angles in degrees) in
    time order; headings_deg: (T,) the decided (smoothed) heading, degrees; evidence_weight:
    each frame's heading evidence is multiplied by it (the frame-rate ratio, as the chain's
    evidence). Returns (T, 55): each frame's chosen member, whole."""
    limbs = np.asarray(limbs, dtype=np.float64)
    headings = np.asarray(headings_deg, dtype=np.float64)
    if limbs.ndim != 2 or limbs.shape[1] != 55 or headings.shape != (len(limbs),):
        raise ValueError(f"limbs must be (T, 55) and headings (T,), got {limbs.shape} and "
                         f"{headings.shape}")
    if len(limbs) == 0:
        return limbs.copy()
    pair = np.stack([limbs, front_back_flip(limbs)], axis=1)                 # (T, 2, 55)
    off = wrap_deg(heading_deg(pair.reshape(-1, 55)).reshape(-1, 2) - headings[:, None])
    log_weight = -evidence_weight * off ** 2 / (2.0 * heading_sd_deg ** 2)
    path = most_probable_path(pair[:, :, 2:], log_weight, step_variance, period=360.0)
    return pair[np.arange(len(pair)), path]
