"""People who cross, as one blob: the Associator's groups (docs/crossings.md). Loaded only once
two confirmed tracks are seen in one frame.

A detection whose box holds the predictions of two or more confirmed tracks (seen last frame or
already in a group, side by side, matched to no other detection) is a group: given to none of
them, its members coast inside it and each gets its share of the blob by its last own shape.
"""
from __future__ import annotations

import numpy as np

from tracker.tracks.association import Associator, Track


def hide_groups(associator: Associator, matched: dict[int, int], boxes: np.ndarray
                ) -> dict[int, np.ndarray]:
    """Detection index -> rows (M,) of the tracks hidden in it, of boxes (N, 4) px; each group
    is taken out of ``matched`` (detection -> track row) and its members coast inside it."""
    groups = find_groups(associator, matched, boxes)
    for j, members in groups.items():
        matched.pop(j, None)
        for r in members:
            _coast_inside(associator.tracks[r], boxes[j])
    return groups


def find_groups(associator: Associator, matched: dict[int, int], boxes: np.ndarray
                ) -> dict[int, np.ndarray]:
    """The groups (module docstring) among boxes (N, 4) px: detection index -> track rows (M,).
    Members are at least ``min_height_ratio`` of the tallest one's height and overlap its rows
    by that share of their own (a leg cut off by the extractor is no person beside it)."""
    tracks, ratio = associator.tracks, associator.min_height_ratio
    eligible = np.array([t.track_id >= 0 and t.missed == 0 and t.hits >= associator.min_hits
                         and t.occluded < associator.max_occluded for t in tracks])
    if not len(boxes) or eligible.sum() < 2:
        return {}
    predicted = np.array([t.predicted() for t in tracks])                 # (T, 2)
    x0, y0, w, h = (boxes[:, i][None, :] for i in range(4))
    px, py = predicted[:, :1], predicted[:, 1:]
    inside = (px >= x0) & (px <= x0 + w) & (py >= y0) & (py <= y0 + h)      # (T, N)
    owner = np.full(len(tracks), -1)
    owner[list(matched.values())] = list(matched.keys())
    member = inside & eligible[:, None] & ((owner[:, None] == -1) |
                                           (owner[:, None] == np.arange(len(boxes))))
    tops = np.array([t.bbox[1] for t in tracks])
    heights = np.array([t.bbox[3] for t in tracks])
    groups, taken = {}, np.zeros(len(tracks), bool)
    for j in np.flatnonzero(member.sum(axis=0) >= 2):
        rows = np.flatnonzero(member[:, j] & ~taken)
        if len(rows) < 2:               # its tracks were taken by an overlapping box
            continue
        tall = rows[np.argmax(heights[rows])]
        beside = (np.minimum(tops[rows] + heights[rows], tops[tall] + heights[tall])
                  - np.maximum(tops[rows], tops[tall]))
        rows = rows[(heights[rows] >= ratio * heights[tall]) & (beside >= ratio * heights[rows])]
        if len(rows) >= 2:
            groups[int(j)] = rows
            taken[rows] = True
    return groups


def split_group(associator: Associator, blob, members: np.ndarray) -> list[tuple[int, object]]:
    """(track_id, part) of the members (track rows (M,)) that get a part of ``blob`` split
    by their last shapes at their coasted boxes ([] without the masks or boxes)."""
    tracks = [associator.tracks[r] for r in members]
    if getattr(blob, "mask", None) is None or any(
            t.shape is None or not np.isfinite(t.bbox).all() for t in tracks):
        return []
    from tracker.video.blob_split import Shape, split_blob
    parts = split_blob(blob, [Shape(t.shape, tuple(t.bbox)) for t in tracks])
    return [(t.track_id, part) for t, part in zip(tracks, parts) if part is not None]


def _coast_inside(track: Track, box: np.ndarray) -> None:
    """Move a track hidden in a group's box (x, y, w, h) px on to its prediction, kept inside
    the box (its own box with it)."""
    centre = np.clip(track.predicted(), box[:2], box[:2] + box[2:])
    track.bbox = track.bbox + np.r_[centre - track.centroid, 0.0, 0.0]
    track.centroid = centre
    track.missed = 0
    track.occluded += 1
