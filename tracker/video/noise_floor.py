"""The background model's noise floor, chosen per clip from how speckled its foreground is.

A background primed from one image has every MOG2 variance at the floor ``varMin`` (4 grey
levels squared by default), which suits a clean camera. Around a moving person a compressed
video's codec smears the background by more than that, so MOG2 marks a speckled halo a few px
thick round the body; cleaned, it closes the gaps between the limbs and the regressor reads
every pose as the same blob. The halo is mostly specks (isolated pixels a 3 px opening
removes): their share of the solid foreground measures the noise without ground truth.
:func:`choose_var_min` takes the lowest floor of a ladder whose specks exceed the top rung's by
at most ``max_excess_specks`` and whose foreground is at most ``max_growth`` times the top
rung's (strong noise can make a low floor's foreground one solid sheet with few specks).
The floors measured on real and rendered clips: docs/tuning.md.
"""
from __future__ import annotations

from typing import Callable, Sequence

import cv2
import numpy as np

#: MOG2 variance floors tried, grey levels squared (MOG2's own default is 4).
VAR_MIN_LADDER: tuple[float, ...] = (4.0, 9.0, 16.0, 25.0, 36.0)
#: Specks per pixel of opened foreground allowed above what the ladder's top rung leaves.
MAX_EXCESS_SPECKS = 0.05
#: Foreground allowed, as a multiple of what the ladder's top rung leaves.
MAX_FOREGROUND_GROWTH = 2.0

#: MOG2 marks foreground 255, shadow 127 and background 0: above this is foreground proper
#: (the silhouette extractor's threshold too).
FOREGROUND_LEVEL = 200
_OPEN_KERNEL = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))


def foreground_counts(model, frames: Sequence[np.ndarray]) -> tuple[int, int]:
    """(specks, solid) pixel counts summed over ``frames`` (each BGR uint8 (h, w, 3) at the
    model's size) when a primed MOG2 ``model`` (not updated: learning rate 0) looks at them.
    Specks are foreground pixels a 3 px elliptical opening removes, solid the rest."""
    specks = solid = 0
    for frame in frames:
        foreground = (model.apply(frame, learningRate=0.0) > FOREGROUND_LEVEL).astype(np.uint8)
        kept = int(cv2.morphologyEx(foreground, cv2.MORPH_OPEN, _OPEN_KERNEL).sum())
        specks += int(foreground.sum()) - kept
        solid += kept
    return specks, solid


def _ratio(specks: int, solid: int) -> float:
    if solid == 0:
        return 0.0 if specks == 0 else float("inf")
    return specks / solid


def speck_ratio(model, frames: Sequence[np.ndarray]) -> float:
    """Specks per pixel of solid foreground (foreground_counts); 0.0 when nothing is
    foreground at all, inf when only specks are."""
    return _ratio(*foreground_counts(model, frames))


def choose_var_min(make_primed_model: Callable[[float], object], frames: Sequence[np.ndarray],
                   ladder: Sequence[float] = VAR_MIN_LADDER,
                   max_excess_specks: float = MAX_EXCESS_SPECKS,
                   max_growth: float = MAX_FOREGROUND_GROWTH) -> float:
    """The lowest MOG2 variance floor (grey levels squared) in ``ladder`` whose foreground on
    ``frames`` has at most ``max_excess_specks`` more specks (:func:`speck_ratio`) than the
    ladder's top rung, and at most ``max_growth`` times the top rung's foreground. The specks a
    higher floor would still remove are noise; those left at the top are not (JPEG blocks, a
    person's small movements) and no floor should chase them. The growth bound catches noise so
    strong that a low floor makes nearly the whole frame solid foreground (no specks left to
    count). make_primed_model(var_min): a fresh MOG2 with the subtractor's other settings that
    has learned the background (BackgroundSubtractor.primed_model); frames: BGR uint8 at the
    working size, spread over the clip. A few hundred MOG2 applications at working size:
    ~0.1 s. Frames with nothing solid at the top rung, only specks (an empty, noisy scene), get
    the top rung."""
    if not len(ladder):
        raise ValueError("the variance floor ladder is empty")
    counts = [foreground_counts(make_primed_model(float(var_min)), frames) for var_min in ladder]
    top_ratio, top_total = _ratio(*counts[-1]), sum(counts[-1])
    if not np.isfinite(top_ratio):           # only specks even at the top: all noise, no body
        return float(ladder[-1])
    for var_min, (specks, solid) in zip(ladder, counts):
        if (_ratio(specks, solid) - top_ratio <= max_excess_specks
                and specks + solid <= max_growth * max(top_total, 1)):
            return float(var_min)
    return float(ladder[-1])
