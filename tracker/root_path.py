"""Each track's root (hip) path smoothed over the whole track, for the smoothed outputs.

The root is not measured in 3-D: each frame's is placed from the silhouette's box alone
(tracker.sinks.geometry.ground_position_from_image: depth from an assumed body height and
field of view), so it jitters with the box as the limbs move (on the sample its depth
strays 45 mm (standard deviation) about its own 15-frame mean, the truth's 5 mm once scaled
alike; a review's measurement, 2026-12-04). The smoothed outputs
(JSON, BVH, the MCAP's /smoothed topics) draw their bodies at the root smoothed here: a
Gaussian over time, zero phase, since the whole track is known; with ``--lag`` the streamed
outputs (the live view, the MCAP's /pose and /skeleton) are drawn at the same path smoothed
over their window (tracker.fixed_lag), without one at each frame's own root.

ROOT_SMOOTHING_S was chosen on the 12 validation videos (five trials as spiral walks and
seven from a fixed camera; one-off driver /work/tmp/s46/root_sigma.py, 2026-12-04): the root's
RMS distance from the truth's hips (lateral and depth, the depth scaled per video by least
squares, since the assumed field of view is not the render's), mean over videos, for a sigma
of 0 / 0.033 / 0.067 / 0.1 / 0.15 / 0.2 / 0.3 / 0.5 s: 170 / 150 / 135 / 128 / 128 / 130 / 139
/ 173 mm; the path's mean second difference 167 / 41 / 14 / 6.4 / 2.4 / 1.5 / 1.0 / 0.7 mm per
frame squared. 0.1 s: as near as 0.15 s, lagging less where the body moves fast (07_12, a
jump: 92 against 108 mm).
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

#: Standard deviation of the Gaussian over time, seconds (module docstring).
ROOT_SMOOTHING_S = 0.1


def smoothed_roots(roots_m: np.ndarray, fps: float, sigma_s: float = ROOT_SMOOTHING_S
                   ) -> np.ndarray:
    """roots_m (T, 3) metres, one track's root per frame in time order at fps frames per
    second, smoothed by a Gaussian of sigma_s seconds (0: unchanged); the ends are extended
    by their own values. Returns (T, 3) metres."""
    roots = np.asarray(roots_m, dtype=np.float64)
    if roots.ndim != 2 or roots.shape[1] != 3:
        raise ValueError(f"roots must be (T, 3), got {roots.shape}")
    if not (np.isfinite(fps) and fps > 0 and np.isfinite(sigma_s) and sigma_s >= 0):
        raise ValueError(f"fps={fps} must be > 0 and sigma_s={sigma_s} >= 0")
    if sigma_s == 0 or len(roots) < 2:
        return roots.copy()
    return gaussian_filter1d(roots, sigma_s * fps, axis=0, mode="nearest")
