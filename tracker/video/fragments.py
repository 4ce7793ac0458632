"""Pieces of one person's foreground joined (a person cut at the waist, a foot or hand apart):
imported by tracker.video.silhouettes.person_masks only for frames with several components."""
from __future__ import annotations

import cv2
import numpy as np

# People side by side do not overlap in x and are of like size; one standing behind another
# usually touches them and is one component anyway.
_MIN_OVERLAP = 0.5               # x-overlap, a share of the narrower piece
_MAX_GAP = 0.25                  # vertical gap, a share of the taller piece


def fragment_groups(rects: np.ndarray, areas: np.ndarray, max_fragment_area: float
                    ) -> list[list[int]]:
    """Groups of components (rects (n, 4) x, y, w, h px; areas (n,) px) that are pieces of one
    person (cut at the waist or neck, a foot or hand apart): x-ranges overlapping by
    _MIN_OVERLAP of the narrower and a vertical gap of at most _MAX_GAP of the taller; or
    the smaller at most ``max_fragment_area`` of the larger's area, within _MAX_GAP of its
    height on every side, its centre not above the larger's top."""
    n = len(rects)
    group = list(range(n))

    def root(i: int) -> int:
        while group[i] != i:
            i = group[i]
        return i

    x0, y0 = rects[:, 0], rects[:, 1]
    x1, y1 = x0 + rects[:, 2], y0 + rects[:, 3]
    overlap = np.minimum(x1[:, None], x1[None, :]) - np.maximum(x0[:, None], x0[None, :])
    narrower = np.minimum(rects[:, 2][:, None], rects[:, 2][None, :])
    gap = np.maximum(y0[:, None], y0[None, :]) - np.minimum(y1[:, None], y1[None, :])
    taller = np.maximum(rects[:, 3][:, None], rects[:, 3][None, :])
    reach = _MAX_GAP * taller
    small = areas[:, None] <= max_fragment_area * areas[None, :]          # i a fragment of j
    fragment = small & (-overlap <= reach) & (gap <= reach) & \
        ((y0 + rects[:, 3] / 2)[:, None] >= y0[None, :])                  # centre below top
    joined = (overlap >= _MIN_OVERLAP * narrower) & (gap <= reach) | fragment | fragment.T
    for i, j in zip(*np.nonzero(np.triu(joined, 1))):
        group[root(int(j))] = root(int(i))
    groups: dict[int, list[int]] = {}
    for i in range(n):
        groups.setdefault(root(i), []).append(i)
    return list(groups.values())


def bridge_vertical_gaps(crop: np.ndarray, rects) -> np.ndarray:
    """Close the vertical gaps between pieces with a vertical closing just taller than the
    widest gap (padded, so background open to the crop's edge is never filled)."""
    tops = sorted((r[1], r[1] + r[3]) for r in rects)
    widest = max([0] + [b_top - a_bottom for (_, a_bottom), (b_top, _) in zip(tops, tops[1:])])
    k = int(widest) + 3
    k += 1 - k % 2                # odd: an even kernel's off-centre anchor shifts the closing
    padded = cv2.copyMakeBorder(crop, k, k, 0, 0, cv2.BORDER_CONSTANT, value=0)
    kernel = np.ones((k, 1), np.uint8)
    closed = cv2.morphologyEx(padded, cv2.MORPH_CLOSE, kernel)
    return closed[k:-k]
