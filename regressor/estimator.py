"""The one interface the tracker calls on a trained model (regressor.pose_model.PoseModel);
a model's optional parts show up as None, NaN or False in its answers, never as missing
methods. Poses (55,): regressor/angles.py; D: a frame's descriptor length; k: stack depth.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from .canonical_priors import CanonicalPriors


@dataclass
class PoseEstimates:
    """A model's answer for N rows of stacked descriptors (PoseEstimator.hypotheses): poses
    (N, m, 55): the m most probable experts' poses, most probable first (m = 1 and
    probabilities 1 for a single regressor); probabilities (N, m): the gate's; limbs (N, 55):
    the limbs' canonical pose or None; mirror_limbs (N, 55): the mirror images' limbs (not
    mirrored back) or None; front (N,): the side classifier's P(the body faces the camera's
    half), None unless the model gives canonical pairs; novelty (N,): unlikeness to the
    training silhouettes (pose_model.UNFAMILIAR_NOVELTY), NaN when unknown or not asked.
    """

    poses: np.ndarray
    probabilities: np.ndarray
    limbs: np.ndarray | None = None
    mirror_limbs: np.ndarray | None = None
    front: np.ndarray | None = None
    novelty: np.ndarray | None = None


@runtime_checkable
class PoseEstimator(Protocol):
    """What the tracker needs of a trained model, all of it. stack_depth: k; training_fps: the
    frame rate (frames/s) the model learned at; measurement_covariance (54, 54) deg^2 and
    process_noise (54,) (deg/s^2)^2: the filter's R and q (heading, then the 53 angles);
    ambiguity_threshold: raw heading norm below which a frame is ambiguous; canonical_direction
    (55,) or None: fitted on canonical members (no separate limb filter then);
    gives_canonical_pairs: the front/back hypotheses are the limbs' canonical member and its
    flip, weighed by the side classifier with canonical_priors (None: the tracker's default);
    limbs_see_mirror: the tracker also asks for each frame's mirror image's limbs.
    """

    stack_depth: int
    training_fps: float
    measurement_covariance: np.ndarray
    process_noise: np.ndarray
    ambiguity_threshold: float
    canonical_direction: np.ndarray | None
    gives_canonical_pairs: bool
    canonical_priors: CanonicalPriors | None
    limbs_see_mirror: bool

    def describe(self, mask: np.ndarray) -> np.ndarray:
        """Descriptor (D,) of a mask (H, W) bool; regressor.edges.SilhouetteError if none."""

    def describe_with_mirror(self, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(describe(mask), the descriptor of the mask's mirror image), (D,) each."""

    def hypotheses(self, stacked: np.ndarray, m: int = 1, mirrored: np.ndarray | None = None,
                   novelty: bool = True) -> PoseEstimates:
        """The answer for stacked descriptors (N, k*D) with the m most probable experts' poses;
        mirrored (N, k*D): the mirror images' stacked descriptors (their limbs come back as
        mirror_limbs); novelty False: not computed (NaN)."""
