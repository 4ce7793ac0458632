"""The one interface the tracker calls on a trained model (regressor.pose_model.PoseModel
implements it).

The tracker (tracker.pipeline, tracker.tracks.hypotheses) uses these members and no others, and
never asks whether a model has one: a model's optional parts (limb networks, side classifier,
heading index) show up as None, NaN or False in what it answers, not as missing methods.

Pose vectors (55,) are the pose vector's layout (regressor/angles.py): the heading as
(cos, sin), then 53 joint angles in degrees. D: one frame's descriptor length; k: the stack
depth (k*D: one row of stacked descriptors).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from .canonical_priors import CanonicalPriors


@dataclass
class PoseEstimates:
    """A model's answer for N rows of stacked descriptors (:meth:`PoseEstimator.hypotheses`).

    poses (N, m, 55): raw poses of the m most probable experts, most probable first (a single
    regressor: m = 1); probabilities (N, m): the gate's probability of each (1 for a single
    regressor); limbs (N, 55): the limb networks' (or limb head's) canonical pose, either body
    of the silhouette, or None for a model without limbs; mirror_limbs (N, 55): the limbs of
    the frames' mirror images (their own bodies, not mirrored back), when asked for and the
    model has limbs, else None; front (N,): the side classifier's probability that the body
    faces the camera's half, None unless the model gives canonical pairs; novelty (N,): how
    unlike the training silhouettes each row is (unitless; above
    regressor.pose_model.UNFAMILIAR_NOVELTY: unfamiliar), NaN when unknown or not asked.
    """

    poses: np.ndarray
    probabilities: np.ndarray
    limbs: np.ndarray | None = None
    mirror_limbs: np.ndarray | None = None
    front: np.ndarray | None = None
    novelty: np.ndarray | None = None


@runtime_checkable
class PoseEstimator(Protocol):
    """What the tracker needs of a trained model, all of it.

    stack_depth: k frames per stacked row; training_fps: the frame rate (frames/s) the stacked
    input and the front/back chain's per-frame figures were learned at;
    measurement_covariance (54, 54) deg^2 and process_noise (54,) (deg/s^2)^2: the Kalman
    filter's R and q (heading, then the 53 angles); ambiguity_threshold: the raw heading norm
    below which a frame is ambiguous, as the model was trained with.
    canonical_direction (55,) or None: set when the model was fitted on canonical members (its
    raw pose may be either body; the tracker then runs no separate limb filter).
    gives_canonical_pairs: the front/back hypotheses are the limbs' canonical member and its
    flip, weighed by the side classifier (tracker.tracks.hypotheses.canonical_hypotheses);
    canonical_priors: the model's own weighing of them, or None (the tracker's default).
    limbs_see_mirror: the limbs answer for a frame's mirror image too (tracker.tracks.mirror_limbs):
    the tracker then describes each frame's mirror image and asks for its limbs.
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
        """Descriptor (D,) of a silhouette mask (H, W) bool; raises
        regressor.edges.SilhouetteError for a mask that has none."""

    def describe_with_mirror(self, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(describe(mask), the descriptor of the mask's mirror image), (D,) each."""

    def hypotheses(self, stacked: np.ndarray, m: int = 1, mirrored: np.ndarray | None = None,
                   novelty: bool = True) -> PoseEstimates:
        """The model's answer (:class:`PoseEstimates`) for stacked descriptors (N, k*D), with
        the m most probable experts' poses; mirrored (N, k*D): the frames' mirror images'
        stacked descriptors, whose limbs come back as mirror_limbs; novelty False: not
        computed (NaN)."""
