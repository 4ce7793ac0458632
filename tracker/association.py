"""Track association: give each person detection a track id that persists from frame to frame.

Each track remembers its centroid, a smoothed velocity (px/frame), its area and, when detections
carry one (``bbox``, as silhouettes.PersonMask does), its last bounding box. Per frame, every
track predicts where it is now (constant velocity), a cost matrix compares predictions with
detections, and the Hungarian algorithm (scipy's linear_sum_assignment) pairs them. Costs are in
units of the track's size (its box height, or sqrt(area) for detections without a box), so the
same gates work for near and far people:

    cost = |centroid - predicted| / size + size_weight * |ln(detection area / track area)|

A pair is refused (gated) when the distance exceeds ``max_distance`` sizes (widened by one size per
missed frame while a track coasts), or the areas differ by more than ``max_area_ratio`` while the
boxes do not overlap: a silhouette that grows or shrinks in place (legs found or lost by the
extractor) keeps its id, a different-sized blob elsewhere does not.
An unmatched detection starts a track at once when it is at least ``min_relative_area`` of the
largest confirmed track's area (or no track is confirmed: the first people of a video are not
delayed); a smaller one starts a tentative track, which gets an id and is reported once matched
in ``min_hits`` consecutive frames, so a blob that flickers for a frame or two beside a tracked
person (light on the floor, a reflection) never becomes a track. A track
unmatched for more than ``max_missed`` frames is dropped, so a person who leaves and comes back
later gets a new id.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol, TypeVar

import numpy as np
from scipy.optimize import linear_sum_assignment

from regressor.errors import SilhouettePoseError


class Detection(Protocol):
    """Anything with a centroid (x, y) px and an area px, e.g. silhouettes.PersonMask; an
    optional ``bbox`` (x, y, w, h) px is used when present."""

    centroid: tuple[float, float]
    area: int


D = TypeVar("D", bound=Detection)


class AssociationError(SilhouettePoseError, ValueError):
    """Bad association settings or detections; one-line message naming the problem."""


@dataclass
class Track:
    """A person followed over frames. ``centroid`` (x, y) px at the last match, ``velocity``
    (vx, vy) px/frame smoothed, ``area`` px smoothed, ``bbox`` (x, y, w, h) px at the last match
    (nan when detections have none), ``hits`` frames matched, ``missed`` consecutive frames
    unmatched, ``track_id`` -1 while the track is tentative (fewer than min_hits hits)."""

    track_id: int
    centroid: np.ndarray
    area: float
    bbox: np.ndarray = field(default_factory=lambda: np.full(4, np.nan))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))
    hits: int = 1
    missed: int = 0

    def predicted(self) -> np.ndarray:
        """(x, y) px expected this frame: the last centroid moved on by the missed frames + 1."""
        return self.centroid + self.velocity * (self.missed + 1)

    def size(self) -> float:
        """The unit of distance, px: the box height, else sqrt(area)."""
        return float(self.bbox[3]) if np.isfinite(self.bbox[3]) else math.sqrt(self.area)


def box_overlap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection over the smaller box's area, (A, B), of boxes a (A, 4) and b (B, 4)
    (x, y, w, h) px; 0 where a box is nan. 1 when one box holds the other."""
    ax0, ay0, aw, ah = (a[:, i][:, None] for i in range(4))
    bx0, by0, bw, bh = (b[:, i][None, :] for i in range(4))
    iw = np.minimum(ax0 + aw, bx0 + bw) - np.maximum(ax0, bx0)
    ih = np.minimum(ay0 + ah, by0 + bh) - np.maximum(ay0, by0)
    inter = np.clip(iw, 0, None) * np.clip(ih, 0, None)
    smaller = np.minimum(aw * ah, bw * bh)
    with np.errstate(invalid="ignore", divide="ignore"):
        overlap = inter / smaller
    return np.nan_to_num(overlap, nan=0.0, posinf=0.0)


class Associator:
    """Frame-to-frame association of detections to track ids (see the module docstring).

    ``max_distance``: gate on centroid distance, in track sizes (box height, or sqrt of area).
    ``max_area_ratio``: gate on the ratio of areas (>= 1), applied when the boxes overlap by
    less than ``min_box_overlap`` (intersection over the smaller box). ``size_weight``: weight
    of the log area ratio in the cost. ``max_missed``: frames a track may go unmatched before
    it is dropped. ``smoothing``: weight of the newest observation in the velocity and area
    updates. ``min_hits``: consecutive frames a new track smaller than ``min_relative_area`` of
    the largest confirmed track must be matched in before it gets an id and its detections are
    returned (1: at once). ``use_boxes``: False ignores detections' boxes
    (sizes from sqrt(area), the area gate always applies: the associator before issue 11).
    """

    def __init__(self, max_distance: float = 1.0, max_area_ratio: float = 1.8,
                 size_weight: float = 1.0, max_missed: int = 15, smoothing: float = 0.5,
                 min_box_overlap: float = 0.5, min_hits: int = 3,
                 min_relative_area: float = 0.25, use_boxes: bool = True):
        if max_distance <= 0 or max_area_ratio < 1 or size_weight < 0 or max_missed < 0:
            raise AssociationError(
                f"need max_distance > 0, max_area_ratio >= 1, size_weight >= 0, max_missed >= 0; "
                f"got {max_distance}, {max_area_ratio}, {size_weight}, {max_missed}")
        if not 0 < smoothing <= 1:
            raise AssociationError(f"smoothing={smoothing} must be in (0, 1]")
        if min_hits < 1 or not 0 < min_box_overlap <= 1:
            raise AssociationError(f"need min_hits >= 1 and min_box_overlap in (0, 1]; got "
                                   f"{min_hits}, {min_box_overlap}")
        self.max_distance = max_distance
        self.max_log_area_ratio = math.log(max_area_ratio)
        self.size_weight = size_weight
        self.max_missed = max_missed
        self.smoothing = smoothing
        self.min_box_overlap = min_box_overlap
        self.min_hits = min_hits
        self.min_relative_area = min_relative_area
        self.use_boxes = use_boxes
        self.tracks: list[Track] = []
        self._next_id = 0

    def cost_matrix(self, centroids: np.ndarray, areas: np.ndarray,
                    boxes: np.ndarray | None = None) -> np.ndarray:
        """Costs (tracks, detections) for centroids (N, 2) px, areas (N,) px and boxes (N, 4)
        px (x, y, w, h; nan or None: unknown); inf = gated."""
        if not self.tracks:
            return np.zeros((0, len(areas)))
        if boxes is None:
            boxes = np.full((len(areas), 4), np.nan)
        predicted = np.array([t.predicted() for t in self.tracks])           # (T, 2)
        track_area = np.array([t.area for t in self.tracks])                  # (T,)
        missed = np.array([t.missed for t in self.tracks])                    # (T,)
        size = np.array([t.size() for t in self.tracks])[:, None]             # (T, 1)
        distance = np.linalg.norm(predicted[:, None, :] - centroids[None, :, :], axis=2) / size
        log_ratio = np.abs(np.log(areas[None, :] / track_area[:, None]))
        overlap = box_overlap(np.array([t.bbox for t in self.tracks]), boxes)
        cost = distance + self.size_weight * log_ratio
        gated = (distance > self.max_distance * (1 + missed[:, None])) | \
                ((log_ratio > self.max_log_area_ratio) & (overlap < self.min_box_overlap))
        cost[gated] = np.inf
        return cost

    def update(self, detections: Sequence[D]) -> list[tuple[int, D]]:
        """Match this frame's detections to tracks; returns (track_id, detection) for each
        detection on a confirmed track (all of them with min_hits=1), in the order given.
        Unmatched detections start tentative tracks; stale tracks are dropped."""
        centroids = np.array([d.centroid for d in detections], float).reshape(-1, 2)
        areas = np.array([d.area for d in detections], float)
        boxes = np.array([_box(d) if self.use_boxes else (np.nan,) * 4 for d in detections],
                         float).reshape(-1, 4)
        if not (np.isfinite(centroids).all() and (areas > 0).all()):
            raise AssociationError("detections need finite centroids and positive areas")
        cost = self.cost_matrix(centroids, areas, boxes)
        finite = np.where(np.isfinite(cost), cost, 1e9)  # gated pairs can never win over new ids
        rows, cols = linear_sum_assignment(finite)
        matched = {c: r for r, c in zip(rows, cols) if np.isfinite(cost[r, c])}

        largest = max((t.area for t in self.tracks if t.track_id >= 0), default=0.0)
        pairs = []
        for j in range(len(detections)):
            if j in matched:
                track = self.tracks[matched[j]]
                self._observe(track, centroids[j], areas[j], boxes[j])
            else:
                track = Track(-1, centroids[j].copy(), float(areas[j]), boxes[j].copy())
                self.tracks.append(track)
            if track.track_id < 0 and (track.hits >= self.min_hits or
                                       areas[j] >= self.min_relative_area * largest):
                track.track_id = self._next_id
                self._next_id += 1
            if track.track_id >= 0:
                pairs.append((track.track_id, detections[j]))
        matched_tracks = {id(self.tracks[r]) for r in matched.values()}
        for track in self.tracks[: len(cost)]:
            if id(track) not in matched_tracks:
                track.missed += 1
        # A tentative track must be seen in consecutive frames.
        self.tracks = [t for t in self.tracks if t.missed <= self.max_missed
                       and (t.track_id >= 0 or t.missed == 0)]
        return pairs

    def _observe(self, track: Track, centroid: np.ndarray, area: float,
                 bbox: np.ndarray) -> None:
        """Fold a matched detection into a track's velocity, area, box and position."""
        step = (centroid - track.centroid) / (track.missed + 1)
        a = self.smoothing
        track.velocity = (1 - a) * track.velocity + a * step if track.hits > 1 else step
        track.area = (1 - a) * track.area + a * area
        track.centroid = centroid.copy()
        track.bbox = bbox.copy()
        track.hits += 1
        track.missed = 0


def _box(detection) -> tuple:
    """A detection's (x, y, w, h) px, nan when it has no ``bbox``."""
    box = getattr(detection, "bbox", None)
    return (np.nan,) * 4 if box is None else tuple(box)
