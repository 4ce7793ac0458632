"""Descriptors and shape contexts of many silhouettes at once (regressor.descriptor), for
training and evaluation."""
from __future__ import annotations

from typing import Callable, Iterable

import numpy as np

from .codebook import Codebook, CodebookError, soft_histogram
from .descriptor import DescriptorSettings, check_codebook, mask_contexts
from .edges import SilhouetteError

Progress = Callable[[int], None]


def descriptors_for_masks(
    masks: Iterable[np.ndarray],
    settings: DescriptorSettings,
    codebook: Codebook,
    progress: Progress | None = None,
) -> np.ndarray:
    """Descriptors of many silhouettes.

    masks: iterable of (H_i, W_i) silhouettes (sizes may differ).
    progress: called with the number of masks done so far after each mask.
    Returns (N, K) float64. Raises DegenerateSilhouetteError naming the index of the first
    unusable mask.
    """
    check_codebook(settings, codebook)
    rows = []
    for i, mask in enumerate(masks):
        try:
            contexts = mask_contexts(mask, settings)
        except SilhouetteError as err:
            raise type(err)(f"mask {i}: {err}") from err
        rows.append(soft_histogram(contexts, codebook, settings.n_votes, settings.total))
        if progress is not None:
            progress(i + 1)
    return np.array(rows, dtype=np.float64).reshape(len(rows), codebook.n_centres)


def contexts_for_masks(
    masks: Iterable[np.ndarray],
    settings: DescriptorSettings,
    per_mask: int | None = None,
    seed: int = 0,
    progress: Progress | None = None,
) -> np.ndarray:
    """Shape contexts pooled from many silhouettes (the training data of a codebook).

    per_mask: keep at most this many contexts per silhouette, drawn without replacement with a
        Generator seeded by seed (None keeps all n_points).
    Returns (M, settings.context_size) float64. Raises DegenerateSilhouetteError naming the index.
    """
    rng = np.random.default_rng(seed)
    pooled = []
    for i, mask in enumerate(masks):
        try:
            contexts = mask_contexts(mask, settings)
        except SilhouetteError as err:
            raise type(err)(f"mask {i}: {err}") from err
        if per_mask is not None and per_mask < len(contexts):
            contexts = contexts[np.sort(rng.choice(len(contexts), size=per_mask, replace=False))]
        pooled.append(contexts)
        if progress is not None:
            progress(i + 1)
    if not pooled:
        raise CodebookError("no masks given to pool shape contexts from")
    return np.vstack(pooled)
