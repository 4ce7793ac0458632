"""Make clean rendered silhouettes look like the ones the tracker extracts from video.

The data set's renders (sequences.dataset) are crisp, 160 px tall, with every gap between the
legs and between an arm and the torso open. What the tracker's extractor (MOG2 background
subtraction at 320 px working width, then an opening, a closing and hole filling,
tracker/video/silhouettes.py) gives from a video of the same body is different. Measured on the
shipped sample (CMU 16_11 spiral walk, 320x240; the evaluation's own renders of the same
frames): the person is ~117 px tall, the masks are ~4 px wider and cover 1.20x the area, edges
are ragged at the 1-2 px scale, narrow gaps (between the legs, arm and torso) are closed, and
IoU with the clean render of the same frame is only 0.79.

:func:`degrade` reproduces those defects on one mask, in this order: shrink to a random person
height (60-150 px by default) with area averaging; blur like a compressed video; add smooth
random noise to the soft mask and threshold it low (ragged, dilated edges); with some
probability punch holes, bite fragments off the outline, add a shadow at the feet or a
separate speck; then the extractor's own cleaning (``clean_mask``: opening 3 px, closing 5 px)
and splitting (``person_masks``: small holes filled, fragments of one person merged, clutter
dropped) on a 320x240 canvas. The cleaning functions are passed in (``cleaner``) so this
module does not import ``tracker``; :func:`lab.training.noisy_masks` wires them.

Everything is deterministic in the generator passed in.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import cv2
import numpy as np


@dataclass(frozen=True)
class MaskNoise:
    """Strength of each defect. height_px: (low, high) person height after shrinking;
    blur_px: (low, high) Gaussian sigma of the video blur; edge_noise: std of the smooth noise
    added to the soft mask (0..1 units); threshold: (low, high) level the noisy soft mask is
    cut at (below 0.5 dilates); p_holes, p_bite, p_shadow, p_speck: probabilities per mask of
    holes inside the body, a bite out of the outline, a shadow at the feet, a separate speck."""

    height_px: tuple[float, float] = (60.0, 150.0)
    blur_px: tuple[float, float] = (0.5, 1.2)
    edge_noise: float = 0.25
    threshold: tuple[float, float] = (0.25, 0.5)
    p_holes: float = 0.3
    p_bite: float = 0.2
    p_shadow: float = 0.3
    p_speck: float = 0.1
    canvas: tuple[int, int] = (240, 320)


Cleaner = Callable[[np.ndarray, tuple[int, int]], "np.ndarray | None"]


def _ellipse(img: np.ndarray, centre, axes, value: int) -> None:
    cv2.ellipse(img, (int(centre[0]), int(centre[1])), (max(1, int(axes[0])), max(1, int(axes[1]))),
                0, 0, 360, value, -1)


def degrade(mask: np.ndarray, rng: np.random.Generator, noise: MaskNoise = MaskNoise(),
            cleaner: Cleaner | None = None) -> np.ndarray:
    """A video-like version (h, w) bool of a clean silhouette mask (H, W) bool (see the module
    docstring). cleaner(mask uint8 255 = foreground on the canvas, canvas (h, w)) -> the
    person's mask crop (bool) or None; None (the default) skips the extractor's cleaning.
    Returns the clean mask cropped when the degraded one is empty."""
    ys, xs = np.nonzero(mask)
    if len(ys) == 0:
        return mask
    crop = mask[ys.min():ys.max() + 1, xs.min():xs.max() + 1].astype(np.float32)
    H, W = crop.shape
    h = float(rng.uniform(*noise.height_px))
    s = h / H
    pad = 6
    w_new, h_new = max(2, int(round(W * s))), max(2, int(round(H * s)))
    soft = cv2.resize(crop, (w_new, h_new), interpolation=cv2.INTER_AREA)
    soft = cv2.copyMakeBorder(soft, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=0)
    sigma = float(rng.uniform(*noise.blur_px))
    soft = cv2.GaussianBlur(soft, (0, 0), sigma)
    field = rng.normal(0.0, 1.0, soft.shape).astype(np.float32)
    field = cv2.GaussianBlur(field, (0, 0), 0.8)
    field *= noise.edge_noise / max(float(field.std()), 1e-6)
    out = ((soft + field) > rng.uniform(*noise.threshold)).astype(np.uint8) * 255
    hh, ww = out.shape
    body = np.argwhere(out > 0)
    if len(body) == 0:
        return crop > 0
    if rng.random() < noise.p_holes:
        for _ in range(int(rng.integers(1, 4))):
            y, x = body[rng.integers(len(body))]
            _ellipse(out, (x, y), rng.uniform(1, 3, 2) * max(1.0, h / 100), 0)
    if rng.random() < noise.p_bite:
        y, x = body[rng.integers(len(body))]
        _ellipse(out, (x, y), rng.uniform(2, 6, 2) * max(1.0, h / 100), 0)
    if rng.random() < noise.p_shadow:
        bottom = np.argwhere(out > 0)
        yb = bottom[:, 0].max()
        feet = bottom[bottom[:, 0] >= yb - 2]
        xc = feet[:, 1].mean() + rng.normal(0, 3)
        _ellipse(out, (xc, yb - 1), (rng.uniform(0.15, 0.5) * ww, rng.uniform(1, 3)), 255)
    if rng.random() < noise.p_speck:
        _ellipse(out, (rng.uniform(0, ww), rng.uniform(0, hh)), rng.uniform(1, 4, 2), 255)
    if cleaner is not None:
        ch, cw = noise.canvas
        canvas = np.zeros((max(ch, hh + 4), max(cw, ww + 4)), np.uint8)
        y0, x0 = (canvas.shape[0] - hh) // 2, (canvas.shape[1] - ww) // 2
        canvas[y0:y0 + hh, x0:x0 + ww] = out
        person = cleaner(canvas, canvas.shape)
        if person is None or person.sum() < 20:
            return crop > 0
        return person
    ys, xs = np.nonzero(out)
    if len(ys) < 20:
        return crop > 0
    return out[ys.min():ys.max() + 1, xs.min():xs.max() + 1] > 0


def degrade_all(masks: Sequence[np.ndarray], seed: int, noise: MaskNoise = MaskNoise(),
                cleaner: Cleaner | None = None, start: int = 0) -> list[np.ndarray]:
    """degrade() of each mask, mask i with a generator seeded by (seed, start + i), so any
    slice of a data set is reproducible on its own (parallel chunks give the same result)."""
    return [degrade(m, np.random.default_rng([seed, start + i]), noise, cleaner)
            for i, m in enumerate(masks)]
