"""Track association: give each person detection a track id that persists from frame to frame.

Each track remembers its centroid, a smoothed velocity (px/frame) and its area. Per frame, every
track predicts where it is now (constant velocity), a cost matrix compares predictions with
detections, and the Hungarian algorithm (scipy's linear_sum_assignment) pairs them. Costs are in
units of the track's size, so the same gates work for near and far people:

    cost = |centroid - predicted| / sqrt(track area)
           + size_weight * |ln(detection area / track area)|

A pair is refused (gated) when the distance exceeds ``max_distance`` sizes (widened by one size per
missed frame while a track coasts) or the areas differ by more than ``max_area_ratio``.
Unmatched detections start new tracks; a track unmatched for more than ``max_missed`` frames is
dropped, so a person who leaves and comes back later gets a new id.
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
    """Anything with a centroid (x, y) px and an area px, e.g. silhouettes.PersonMask."""

    centroid: tuple[float, float]
    area: int


D = TypeVar("D", bound=Detection)


class AssociationError(SilhouettePoseError, ValueError):
    """Bad association settings or detections; one-line message naming the problem."""


@dataclass
class Track:
    """A person followed over frames. ``centroid`` (x, y) px at the last match, ``velocity``
    (vx, vy) px/frame smoothed, ``area`` px smoothed, ``hits`` frames matched, ``missed``
    consecutive frames unmatched."""

    track_id: int
    centroid: np.ndarray
    area: float
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))
    hits: int = 1
    missed: int = 0

    def predicted(self) -> np.ndarray:
        """(x, y) px expected this frame: the last centroid moved on by the missed frames + 1."""
        return self.centroid + self.velocity * (self.missed + 1)


class Associator:
    """Frame-to-frame association of detections to track ids (see the module docstring).

    ``max_distance``: gate on centroid distance, in track sizes (sqrt of area, px).
    ``max_area_ratio``: gate on the ratio of areas (>= 1). ``size_weight``: weight of the
    log area ratio in the cost. ``max_missed``: frames a track may go unmatched before it is
    dropped. ``smoothing``: weight of the newest observation in the velocity and area updates.
    """

    def __init__(self, max_distance: float = 1.0, max_area_ratio: float = 1.8,
                 size_weight: float = 1.0, max_missed: int = 15, smoothing: float = 0.5):
        if max_distance <= 0 or max_area_ratio < 1 or size_weight < 0 or max_missed < 0:
            raise AssociationError(
                f"need max_distance > 0, max_area_ratio >= 1, size_weight >= 0, max_missed >= 0; "
                f"got {max_distance}, {max_area_ratio}, {size_weight}, {max_missed}")
        if not 0 < smoothing <= 1:
            raise AssociationError(f"smoothing={smoothing} must be in (0, 1]")
        self.max_distance = max_distance
        self.max_log_area_ratio = math.log(max_area_ratio)
        self.size_weight = size_weight
        self.max_missed = max_missed
        self.smoothing = smoothing
        self.tracks: list[Track] = []
        self._next_id = 0

    def cost_matrix(self, centroids: np.ndarray, areas: np.ndarray) -> np.ndarray:
        """Costs (tracks, detections) for centroids (N, 2) px and areas (N,) px; inf = gated."""
        if not self.tracks:
            return np.zeros((0, len(areas)))
        predicted = np.array([t.predicted() for t in self.tracks])           # (T, 2)
        track_area = np.array([t.area for t in self.tracks])                  # (T,)
        missed = np.array([t.missed for t in self.tracks])                    # (T,)
        size = np.sqrt(track_area)[:, None]
        distance = np.linalg.norm(predicted[:, None, :] - centroids[None, :, :], axis=2) / size
        log_ratio = np.abs(np.log(areas[None, :] / track_area[:, None]))
        cost = distance + self.size_weight * log_ratio
        gated = (distance > self.max_distance * (1 + missed[:, None])) | \
                (log_ratio > self.max_log_area_ratio)
        cost[gated] = np.inf
        return cost

    def update(self, detections: Sequence[D]) -> list[tuple[int, D]]:
        """Match this frame's detections to tracks; returns (track_id, detection) per detection,
        in the order given. Unmatched detections get new ids; stale tracks are dropped."""
        centroids = np.array([d.centroid for d in detections], float).reshape(-1, 2)
        areas = np.array([d.area for d in detections], float)
        if not (np.isfinite(centroids).all() and (areas > 0).all()):
            raise AssociationError("detections need finite centroids and positive areas")
        cost = self.cost_matrix(centroids, areas)
        finite = np.where(np.isfinite(cost), cost, 1e9)  # gated pairs can never win over new ids
        rows, cols = linear_sum_assignment(finite)
        matched = {c: r for r, c in zip(rows, cols) if np.isfinite(cost[r, c])}

        ids = []
        for j in range(len(detections)):
            if j in matched:
                track = self.tracks[matched[j]]
                self._observe(track, centroids[j], areas[j])
            else:
                track = Track(self._next_id, centroids[j].copy(), float(areas[j]))
                self._next_id += 1
                self.tracks.append(track)
            ids.append(track.track_id)
        matched_tracks = {id(self.tracks[r]) for r in matched.values()}
        for track in self.tracks[: len(cost)]:
            if id(track) not in matched_tracks:
                track.missed += 1
        self.tracks = [t for t in self.tracks if t.missed <= self.max_missed]
        return list(zip(ids, detections))

    def _observe(self, track: Track, centroid: np.ndarray, area: float) -> None:
        """Fold a matched detection into a track's velocity, area and position."""
        step = (centroid - track.centroid) / (track.missed + 1)
        a = self.smoothing
        track.velocity = (1 - a) * track.velocity + a * step if track.hits > 1 else step
        track.area = (1 - a) * track.area + a * area
        track.centroid = centroid.copy()
        track.hits += 1
        track.missed = 0
