"""Front/back hypotheses of whole descriptor arrays or silhouette sequences, as the tracker
makes them frame by frame (tracker.tracks.hypotheses): for offline evaluation and the learning
of priors (``track`` never loads this)."""
from __future__ import annotations

import numpy as np

from regressor.estimator import PoseEstimator
from regressor.stacking import stack_frames
from tracker.pipeline import FilterFactory, TrackerSettings, filter_factories
from tracker.tracks.hypotheses import (DEFAULT_EXPERTS, FrontBackTracker, Hypotheses,
                                       canonical_priors, chain_options, hypotheses_from)
from tracker.tracks.mirror_limbs import sees_mirror


def front_back_tracker(estimator: PoseEstimator, fps: float,
                       settings: TrackerSettings = TrackerSettings(),
                       filter_factory: FilterFactory | None = None) -> FrontBackTracker:
    """A track's front/back hypotheses with the filters of filter_factories, as PoseTracker
    makes them (for the evaluations)."""
    chain, limbs = filter_factories(estimator, settings, filter_factory)
    return FrontBackTracker(chain, fps, **chain_options(estimator),
                            keep_history=settings.keep_history, limb_filter_factory=limbs)


def propose_batch(estimator: PoseEstimator, stacked: np.ndarray,
                  n_experts: int = DEFAULT_EXPERTS, mirrored: np.ndarray | None = None
                  ) -> list[Hypotheses]:
    """The hypotheses of stacked descriptors (N, k*D), one per row: the estimator's
    ``hypotheses`` with n_experts experts through hypotheses_from. mirrored (N, k*D) or None:
    the mirror images' stacked descriptors (tracker.tracks.mirror_limbs)."""
    estimates = estimator.hypotheses(stacked, n_experts, mirrored=mirrored, novelty=False)
    return hypotheses_from(estimates, canonical_priors(estimator))


def propose_sequence(estimator: PoseEstimator, masks, n_experts: int = DEFAULT_EXPERTS,
                     mirror: bool = True, step: int = 1) -> list[Hypotheses]:
    """The hypotheses of one person's silhouette sequence (masks (H, W) bool, in order), as
    the tracker makes them: each mask described (and its mirror image when
    tracker.tracks.mirror_limbs.sees_mirror), stacked ``step`` frames apart, then
    :func:`propose_batch`."""
    k = estimator.stack_depth
    if sees_mirror(estimator, mirror):
        pairs = [estimator.describe_with_mirror(m) for m in masks]
        X, M = (np.array([p[i] for p in pairs]) for i in (0, 1))
        return propose_batch(estimator, stack_frames(X, k, step=step), n_experts,
                             stack_frames(M, k, step=step))
    X = np.array([estimator.describe(m) for m in masks])
    return propose_batch(estimator, stack_frames(X, k, step=step), n_experts)
