"""Limbs from the image and from its mirror image, averaged.

A model whose limb networks were fitted on mirror images too (the training silhouettes flipped
left to right, their poses mirrored: regressor.training.MixtureOptions.limb_net_mirror;
regressor.pose_model.PoseModel.limbs_see_mirror) answers for a frame's mirror image as well as
for the frame. Its answer for the mirror image, mirrored back (sequences.pose_vector.image_mirror),
is a second estimate of the same body with errors partly independent of the first: the
networks' handedness and their fit differ between the two sides. The tracker averages the
two (``TrackerSettings.mirror_limbs``, on by default). It costs the mirror image's descriptor
(its shape contexts are the frame's own, reflected: PoseModel.describe_with_mirror) and one
more pass of the networks per person and frame.

Measured (2026-12-02, the shipped model with eight mirror-trained networks; chosen on
validation data, one-off drivers): through ``track`` on the five validation videos 02_02 /
08_03 / 05_02 / 09_04 / 02_05 filtered corr8 0.698 / 0.784 / 0.049 / 0.507 / 0.365 -> 0.708 /
0.786 / 0.071 / 0.511 / 0.364 (mean 0.481 -> 0.488), err53 mean 7.69 -> 7.60, knee/elbow
flexion error mean 15.90 -> 15.71; filtered heading RMS 09_04 15.2 -> 20.0 and 02_05 77.4 ->
79.2 (the chain weighs the networks' pair, so the heading moves with them), the others
within 0.2 degree. On the 28 validation renders (lab.hypothesis_priors
.validation_renders, the whole chain): filtered / smoothed heading RMS 36.4 / 28.5 -> 35.2 /
28.1 degrees, corr8 0.561 / 0.630 -> 0.571 / 0.635. Describing the flipped mask itself (its
edge sampled anew, 1.4 ms more per frame instead of 0.34) gave 0.492 on the videos and 0.572
/ 0.635 on the renders. Not adopted: averaging the side classifier's front probability
with the mirror image's too: renders filtered / smoothed heading 35.2 / 28.1 -> 36.0 / 37.5
and corr8 0.571 / 0.635 -> 0.547 / 0.541 (whole-track flips on 08_03 and 09_04 fixed,
reversed). The same average tried earlier with four networks fitted without mirror images
gained nothing through ``track`` (regressor.limb_net's docstring): those networks had not
seen mirror images.
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
