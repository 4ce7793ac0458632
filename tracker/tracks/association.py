"""Track association: give each person detection a track id that persists from frame to frame.

Each track predicts its centroid (constant velocity) and the Hungarian algorithm pairs the
predictions with the detections. Costs are in units of the track's size (its box height, or
sqrt(area) without a box), so one gate serves near and far people:

    cost = |centroid - predicted| / size + size_weight * |ln(detection area / track area)|
           + appearance_weight * Bhattacharyya(detection colour, track colour)

A small new detection gets an id only once matched in consecutive frames (a flickering blob
never becomes a track). People who cross are one blob, a group: tracker.tracks.groups.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol, TypeVar

import numpy as np
from scipy.optimize import linear_sum_assignment

from regressor.errors import SilhouettePoseError

#: Seconds a track may stay in a group (PoseTracker's max_occluded): the sample beside its
#: mirror image is one blob for 0.6 s a crossing.
MAX_OCCLUDED_S = 1.5


class Detection(Protocol):
    """A centroid (x, y) px and area px (e.g. PersonMask); bbox, colour and mask if present."""

    centroid: tuple[float, float]
    area: int


D = TypeVar("D", bound=Detection)


class AssociationError(SilhouettePoseError, ValueError):
    """Bad association settings or detections; one-line message naming the problem."""


@dataclass
class Track:
    """A person: centroid (x, y) px and bbox (x, y, w, h) px (nan: none) at the last match,
    velocity (vx, vy) px/frame and area px smoothed, hits, missed and occluded (in a group)
    frame counts, track_id (-1: tentative), colour and shape (its last own mask, (h, w) bool)."""

    track_id: int
    centroid: np.ndarray
    area: float
    bbox: np.ndarray = field(default_factory=lambda: np.full(4, np.nan))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))
    hits: int = 1
    missed: int = 0
    colour: np.ndarray | None = None
    occluded: int = 0
    shape: np.ndarray | None = None

    def predicted(self) -> np.ndarray:
        """(x, y) px expected this frame (constant velocity since the last match)."""
        return self.centroid + self.velocity * (self.missed + 1)


def box_overlap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection over the smaller box's area (A, B) of boxes a (A, 4), b (B, 4) (x, y, w, h)
    px; 0 where a box is nan."""
    ax0, ay0, aw, ah = (a[:, i][:, None] for i in range(4))
    bx0, by0, bw, bh = (b[:, i][None, :] for i in range(4))
    iw = np.minimum(ax0 + aw, bx0 + bw) - np.maximum(ax0, bx0)
    ih = np.minimum(ay0 + ah, by0 + bh) - np.maximum(ay0, by0)
    inter = np.clip(iw, 0, None) * np.clip(ih, 0, None)
    with np.errstate(invalid="ignore", divide="ignore"):
        overlap = inter / np.minimum(aw * ah, bw * bh)              # over the smaller box
    return np.nan_to_num(overlap, nan=0.0, posinf=0.0)


#: Each setting's allowed values: an interval, open at an end given by a parenthesis.
_LIMITS = {"max_distance": "(0, inf)", "max_area_ratio": "[1, inf)", "size_weight": "[0, inf)",
           "max_missed": "[0, inf)", "smoothing": "(0, 1]", "min_box_overlap": "(0, 1]",
           "min_hits": "[1, inf)", "appearance_weight": "[0, inf)", "colour_rate": "(0, 1]",
           "max_occluded": "[0, inf)", "min_height_ratio": "[0, 1]"}


@dataclass(eq=False)
class Associator:
    """Frame-to-frame association of detections to track ids (see the module docstring). A pair is
    gated beyond ``max_distance`` sizes (one more per frame coasted), or when the areas differ by
    more than ``max_area_ratio`` and the boxes overlap by less than ``min_box_overlap`` (a
    silhouette that grows in place keeps its id). A detection below ``min_relative_area`` of the
    largest track's waits ``min_hits`` frames for its id; a track unmatched ``max_missed`` frames
    is dropped. ``smoothing``, ``colour_rate``: weight of the newest frame in velocity and area,
    colour. ``use_boxes``: False ignores boxes (no groups). ``max_occluded``, ``min_height_ratio``:
    frames in a group (0: none), members' heights (tracker.tracks.groups)."""

    max_distance: float = 1.0
    max_area_ratio: float = 1.8
    size_weight: float = 1.0
    max_missed: int = 15
    smoothing: float = 0.5
    min_box_overlap: float = 0.5
    min_hits: int = 3
    min_relative_area: float = 0.25
    use_boxes: bool = True
    appearance_weight: float = 1.0
    colour_rate: float = 0.1
    max_occluded: int = 45
    min_height_ratio: float = 0.5
    tracks: list[Track] = field(default_factory=list, init=False)
    _next_id: int = field(default=0, init=False, repr=False)

    def __post_init__(self):
        for name, interval in _LIMITS.items():
            low, high = (float(end) for end in interval[1:-1].split(","))
            value = getattr(self, name)
            if not ((low < value if interval[0] == "(" else low <= value) and value <= high):
                raise AssociationError(f"{name}={value} must be in {interval}")

    def cost_matrix(self, centroids: np.ndarray, areas: np.ndarray, boxes: np.ndarray,
                    colours: np.ndarray | None = None) -> np.ndarray:
        """Costs (tracks, detections), inf = gated, for centroids (N, 2) px, areas (N,) px,
        boxes (N, 4) px (nan: unknown) and colour histograms (N, K) or None."""
        if not self.tracks:
            return np.zeros((0, len(areas)))
        predicted = np.array([t.predicted() for t in self.tracks])           # (T, 2)
        track_area = np.array([t.area for t in self.tracks])                  # (T,)
        # Coasting, in a group or unseen, widens the gate by one size a frame.
        missed = np.array([t.missed + t.occluded for t in self.tracks])       # (T,)
        size = np.array([float(t.bbox[3]) if np.isfinite(t.bbox[3]) else math.sqrt(t.area)
                         for t in self.tracks])[:, None]     # (T, 1) unit of distance, px
        distance = np.linalg.norm(predicted[:, None, :] - centroids[None, :, :], axis=2) / size
        log_ratio = np.abs(np.log(areas[None, :] / track_area[:, None]))
        overlap = box_overlap(np.array([t.bbox for t in self.tracks]), boxes)
        cost = distance + self.size_weight * log_ratio
        known = np.array([t.colour is not None for t in self.tracks])           # (T,)
        if colours is not None and self.appearance_weight > 0 and known.any():
            # Bhattacharyya distances (T, N) in [0, 1] (0 for a track without a colour).
            mean = np.stack([t.colour if t.colour is not None else np.zeros(colours.shape[1])
                             for t in self.tracks])
            coefficient = np.sqrt(mean) @ np.sqrt(colours).T
            cost += self.appearance_weight * (np.sqrt(np.clip(1.0 - coefficient, 0.0, 1.0))
                                              * known[:, None])
        gated = (distance > self.max_distance * (1 + missed[:, None])) | \
                ((log_ratio > math.log(self.max_area_ratio)) & (overlap < self.min_box_overlap))
        cost[gated] = np.inf
        return cost

    def update(self, detections: Sequence[D]) -> list[tuple[int, D]]:
        """Match this frame's detections to tracks: (track_id, detection) for each on a
        confirmed track, in order, a group's replaced by (track_id, part) for its members
        (tracker.tracks.groups). Unmatched detections start tentative tracks; stale ones go."""
        centroids = np.array([d.centroid for d in detections], float).reshape(-1, 2)
        areas = np.array([d.area for d in detections], float)
        boxes = [getattr(d, "bbox", None) if self.use_boxes else None for d in detections]
        boxes = np.array([(np.nan,) * 4 if b is None else tuple(b) for b in boxes],
                         float).reshape(-1, 4)
        colours = [getattr(d, "colour", None) for d in detections]   # (N, K) if all have one
        colours = (None if not colours or any(c is None for c in colours)
                   else np.asarray(colours, float))
        if not (np.isfinite(centroids).all() and (areas > 0).all()):
            raise AssociationError("detections need finite centroids and positive areas")
        cost = self.cost_matrix(centroids, areas, boxes, colours)
        finite = np.where(np.isfinite(cost), cost, 1e9)  # gated pairs can never win over new ids
        rows, cols = linear_sum_assignment(finite)
        matched = {c: r for r, c in zip(rows, cols) if np.isfinite(cost[r, c])}
        groups = {}
        if self.max_occluded and sum(t.track_id >= 0 and t.missed == 0 for t in self.tracks) > 1:
            from tracker.tracks.groups import hide_groups   # only where two people are seen
            groups = hide_groups(self, matched, boxes)
        hidden = {id(self.tracks[r]) for members in groups.values() for r in members}
        largest = max((t.area for t in self.tracks if t.track_id >= 0), default=0.0)
        pairs = []
        for j in range(len(detections)):
            if j in groups:
                from tracker.tracks.groups import split_group
                pairs += split_group(self, detections[j], groups[j])
                continue
            colour = None if colours is None else colours[j]
            if j in matched:
                track = self.tracks[matched[j]]
                self._observe(track, centroids[j], areas[j], boxes[j], colour)
            else:
                track = Track(-1, centroids[j].copy(), float(areas[j]), boxes[j].copy(),
                              colour=None if colour is None else colour.copy())
                self.tracks.append(track)
            track.shape = getattr(detections[j], "mask", None)
            if track.track_id < 0 and (track.hits >= self.min_hits or
                                       areas[j] >= self.min_relative_area * largest):
                track.track_id = self._next_id
                self._next_id += 1
            if track.track_id >= 0:
                pairs.append((track.track_id, detections[j]))
        matched_tracks = {id(self.tracks[r]) for r in matched.values()} | hidden
        for track in self.tracks[: len(cost)]:
            if id(track) not in matched_tracks:
                track.missed += 1
                track.occluded = 0
        # A tentative track must be seen in consecutive frames.
        self.tracks = [t for t in self.tracks if t.missed <= self.max_missed
                       and (t.track_id >= 0 or t.missed == 0)]
        return pairs

    def _observe(self, track: Track, centroid: np.ndarray, area: float,
                 bbox: np.ndarray, colour: np.ndarray | None = None) -> None:
        """Fold a matched detection into a track's velocity, area, colour, box and position."""
        step = (centroid - track.centroid) / (track.missed + 1)
        a = self.smoothing
        track.velocity = (1 - a) * track.velocity + a * step if track.hits > 1 else step
        track.area = (1 - a) * track.area + a * area
        if colour is not None:
            if track.colour is None:
                track.colour = colour.copy()
            else:
                rate = max(self.colour_rate, 1.0 / (track.hits + 1))
                track.colour = (1 - rate) * track.colour + rate * colour
        track.centroid = centroid.copy()
        track.bbox = bbox.copy()
        track.hits += 1
        track.missed = 0
        track.occluded = 0
