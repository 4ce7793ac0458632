"""Split one blob that holds several tracked people into one silhouette per person.

Each member track's last own silhouette (a :class:`Shape`) is moved to its predicted box, and
each pixel of the blob goes to the member with the smallest signed distance to its shape's
outline (deepest inside, or nearest): overlaps are cut midway, limbs go to the nearer shape.
The distance work runs on the blob scaled to ``WORK_HEIGHT`` rows, so its cost does not grow
with the frame (docs/crossings.md). A member with under ``min_share`` of its own shape's area
(hidden behind) gets no silhouette rather than a fragment.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from tracker.video.silhouettes import PersonMask

#: Rows of the grid the blob is split on (the blob is scaled to it, never enlarged).
WORK_HEIGHT = 64


@dataclass(frozen=True)
class Shape:
    """A track's silhouette of its own: ``mask`` (h, w) bool and where it should be now,
    ``bbox`` (x, y, w, h) px (float; the mask is stretched to the box's size)."""

    mask: np.ndarray
    bbox: tuple[float, float, float, float]


def split_blob(blob: PersonMask, shapes: list[Shape], min_share: float = 0.3
               ) -> list[PersonMask | None]:
    """One PersonMask per shape (M,) (None for a member that got too little of the blob: under
    ``min_share`` of its shape's area), their pixels partitioning the blob's; colour None
    (the frame is not at hand). Raises ValueError for fewer than two shapes."""
    if len(shapes) < 2:
        raise ValueError(f"a blob is split between two or more shapes, got {len(shapes)}")
    bx, by, bw, bh = blob.bbox
    scale = min(1.0, WORK_HEIGHT / float(bh))
    size = (max(1, round(bw * scale)), max(1, round(bh * scale)))        # (w, h) of the grid
    signed = np.stack([_signed_distance(shape, blob.bbox, scale, size) for shape in shapes])
    labels = np.argmin(signed, axis=0).astype(np.uint8)                  # (h, w) on the grid
    if size != (bw, bh):
        labels = cv2.resize(labels, (bw, bh), interpolation=cv2.INTER_NEAREST)
    parts = []
    for m, shape in enumerate(shapes):
        own = blob.mask & (labels == m)
        expected = float(np.count_nonzero(shape.mask)) * (shape.bbox[2] * shape.bbox[3]) / \
            float(shape.mask.size)
        parts.append(_person(own, bx, by) if np.count_nonzero(own) >= min_share * expected
                     else None)
    return parts


def _signed_distance(shape: Shape, box: tuple[int, int, int, int], scale: float,
                     size: tuple[int, int]) -> np.ndarray:
    """(h, w) float32 over the blob's grid (``box`` (x, y, w, h) px scaled by ``scale`` to
    ``size`` (w, h)): the distance in grid cells to the shape drawn at its box, negative
    inside it (minus the distance to its outline)."""
    sx, sy, sw, sh = shape.bbox
    x0, y0 = (sx - box[0]) * scale, (sy - box[1]) * scale
    w, h = max(1, round(sw * scale)), max(1, round(sh * scale))
    small = cv2.resize(shape.mask.astype(np.uint8), (w, h), interpolation=cv2.INTER_AREA)
    # Translate into a canvas padded by an eighth of the grid: a shape reaching out of the
    # blob keeps its outline there, so a cell near the blob's edge is measured to it.
    # (OpenCV's distance transform takes the image border as no outline.)
    pad = max(4, size[1] // 8)
    shift = np.float32([[1, 0, x0 + pad], [0, 1, y0 + pad]])
    canvas = cv2.warpAffine(small, shift, (size[0] + 2 * pad, size[1] + 2 * pad),
                            flags=cv2.INTER_NEAREST)
    inside = canvas > 0
    if not inside.any():
        return np.full((size[1], size[0]), np.inf, np.float32)
    outside_d = cv2.distanceTransform((~inside).astype(np.uint8), cv2.DIST_L2, 3)
    inside_d = cv2.distanceTransform(inside.astype(np.uint8), cv2.DIST_L2, 3)
    signed = outside_d - inside_d
    return signed[pad:pad + size[1], pad:pad + size[0]]


def _person(mask: np.ndarray, x: int, y: int) -> PersonMask | None:
    """A PersonMask of the True pixels of ``mask`` (h, w) bool placed at (x, y) px in the
    frame: cropped to their box, centroid and area counted; None when empty."""
    rows, cols = np.any(mask, axis=1), np.any(mask, axis=0)
    if not rows.any():
        return None
    r0, r1 = np.flatnonzero(rows)[[0, -1]]
    c0, c1 = np.flatnonzero(cols)[[0, -1]]
    crop = mask[r0:r1 + 1, c0:c1 + 1]
    moments = cv2.moments(crop.astype(np.uint8), binaryImage=True)
    area = int(moments["m00"])
    centroid = (x + c0 + moments["m10"] / area, y + r0 + moments["m01"] / area)
    return PersonMask(crop.copy(), (int(x + c0), int(y + r0), int(c1 - c0 + 1),
                                    int(r1 - r0 + 1)), centroid, area)
