"""Limbs from the image and from its mirror image, averaged (``TrackerSettings.mirror_limbs``):
for a model whose limb networks were fitted on mirror images too (PoseModel.limbs_see_mirror),
the mirror image's limbs mirrored back are a second estimate with partly independent errors."""
from __future__ import annotations

import numpy as np

from regressor.angles import wrap_deg
from regressor.estimator import PoseEstimator
from sequences.pose_vector import image_mirror


def mirror_mean(limbs: np.ndarray, mirror_limbs: np.ndarray) -> np.ndarray:
    """The mean (N, 55) of limbs (N, 55), the model's canonical limbs for the frames, and
    mirror_limbs (N, 55), for their mirror images, mirrored back first: the 53 angles (degrees)
    on the circle, the heading's (cos, sin) as numbers."""
    a = np.asarray(limbs, dtype=np.float64)
    b = image_mirror(np.asarray(mirror_limbs, dtype=np.float64))
    if a.shape != b.shape or a.shape[-1] != 55:
        raise ValueError(f"limbs must be (N, 55) alike, got {a.shape} and {b.shape}")
    out = np.empty_like(a)
    out[..., :2] = (a[..., :2] + b[..., :2]) / 2.0
    out[..., 2:] = wrap_deg(a[..., 2:] + wrap_deg(b[..., 2:] - a[..., 2:]) / 2.0)
    return out


def sees_mirror(estimator: PoseEstimator, enabled: bool = True) -> bool:
    """Whether to describe each frame's mirror image: the setting and the model's say."""
    return enabled and estimator.limbs_see_mirror
