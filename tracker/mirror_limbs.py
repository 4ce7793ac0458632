"""Limbs from the image and from its mirror image, averaged.

A model whose limb networks were fitted on mirror images too (the training silhouettes flipped
left to right, their poses mirrored: tracker.offline.training.MixtureOptions.limb_net_mirror;
regressor.pose_model.PoseModel.limbs_see_mirror) answers for a frame's mirror image as well as
for the frame. Its answer for the mirror image, mirrored back (sequences.pose_vector.image_mirror),
is a second estimate of the same body with errors partly independent of the first: the
networks' handedness and their fit differ between the two sides. The tracker averages the
two (``TrackerSettings.mirror_limbs``, on by default). It costs the mirror image's descriptor
(its shape contexts are the frame's own, reflected: PoseModel.describe_with_mirror) and one
more pass of the networks per person and frame.

Measured (2026-12-02, the shipped model with eight mirror-trained networks, through ``track``
on the five validation videos 02_02 / 08_03 / 05_02 / 09_04 / 02_05; one-off driver):
filtered corr8 0.698 / 0.784 / 0.049 / 0.507 / 0.365 -> 0.717 / 0.791 / 0.075 / 0.515 /
0.361 (mean 0.481 -> 0.492), err53 mean 7.69 -> 7.58, knee/elbow flexion error mean 15.90 ->
15.67; filtered heading RMS mean 36.8 -> 38.1 (09_04 15.2 -> 19.9; the chain weighs the
networks' pair, so the heading moves with them; smoothed 5.9 -> 5.7). The same average tried
earlier with four networks fitted without mirror images gained nothing through ``track``
(regressor.limb_net's docstring): those networks had not seen mirror images.
"""
from __future__ import annotations

import numpy as np

from regressor.angles import wrap_deg
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


def sees_mirror(estimator, enabled: bool = True) -> bool:
    """Whether the tracker should describe each frame's mirror image for this estimator: the
    setting (``enabled``) and the model's own say (PoseModel.limbs_see_mirror, with
    describe_with_mirror and predict_limbs)."""
    return (enabled and bool(getattr(estimator, "limbs_see_mirror", False))
            and hasattr(estimator, "describe_with_mirror")
            and hasattr(estimator, "predict_limbs"))
