"""Limbs from the image and from its mirror image, averaged (``TrackerSettings.mirror_limbs``).

A model whose limb networks were fitted on mirror images too (PoseModel.limbs_see_mirror)
answers for a frame's mirror image as well; mirrored back, that is a second estimate of the
same body with partly independent errors. Measurements: docs/tuning.md.
"""
from __future__ import annotations

import numpy as np

from regressor.angles import wrap_deg
from regressor.estimator import PoseEstimator
from sequences.pose_vector import image_mirror


def mirror_mean(limbs: np.ndarray, mirror_limbs: np.ndarray) -> np.ndarray:
    """The mean of two estimates of the same body: limbs (N, 55), the model's canonical limbs
    for the frames, and mirror_limbs (N, 55), its limbs for the frames' mirror images (the
    mirror images' own bodies). mirror_limbs are mirrored back first; the 53 angles (degrees)
    are averaged on the circle (half the wrapped difference), the heading's (cos, sin) as
    numbers. Returns (N, 55)."""
    a = np.asarray(limbs, dtype=np.float64)
    b = image_mirror(np.asarray(mirror_limbs, dtype=np.float64))
    if a.shape != b.shape or a.shape[-1] != 55:
        raise ValueError(f"limbs must be (N, 55) alike, got {a.shape} and {b.shape}")
    out = np.empty_like(a)
    out[..., :2] = (a[..., :2] + b[..., :2]) / 2.0
    out[..., 2:] = wrap_deg(a[..., 2:] + wrap_deg(b[..., 2:] - a[..., 2:]) / 2.0)
    return out


def sees_mirror(estimator: PoseEstimator, enabled: bool = True) -> bool:
    """Whether the tracker should describe each frame's mirror image for this estimator: the
    setting (``enabled``) and the model's own say (PoseEstimator.limbs_see_mirror)."""
    return enabled and estimator.limbs_see_mirror
