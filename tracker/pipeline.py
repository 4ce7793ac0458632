"""The per-frame tracking loop: frame -> people -> track ids -> pose per track, filtered.

Reads like DESIGN.md's data flow, one stage a line (see PoseTracker.process). The regressor side
is an estimator object (regressor.pose_model.PoseModel) with three things: describe(mask) ->
descriptor, stack_depth, predict(stacked) -> raw 55-D pose; plus the filter's noise models.
"""
from __future__ import annotations

import time
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from regressor.edges import SilhouetteError as DescriptorSilhouetteError
from regressor.stacking import FrameStacker
from .association import Associator
from .filtering import PoseKalmanFilter
from .silhouettes import PersonMask, SilhouetteExtractor
from .skeleton_geometry import ground_position_from_image, pose_joints_m
from .travel import TravelDirection, fuse_heading, resolve_front_back


class PoseEstimator(Protocol):
    """What the tracker needs of a trained model."""

    stack_depth: int
    measurement_covariance: np.ndarray      # (54, 54) deg^2, filter R
    process_noise: np.ndarray               # (54,) (deg/s^2)^2, filter q

    def describe(self, mask: np.ndarray) -> np.ndarray: ...        # (H, W) bool -> (D,)

    def predict(self, stacked: np.ndarray) -> np.ndarray: ...      # (k*D,) -> (55,)


@dataclass
class TrackedPose:
    """One person in one frame. raw/filtered: (55,) pose vectors (degrees; heading as cos,
    sin); ambiguous: raw heading norm below the threshold; centroid_px: (x, y) pixels;
    bbox_px: (x, y, w, h) pixels; joints_m: (18, 3) metres, Y up, for drawing (root placed on
    an approximate ground position from the image)."""

    frame_index: int
    time_s: float
    track_id: int
    raw: np.ndarray
    filtered: np.ndarray
    ambiguous: bool
    centroid_px: tuple[float, float]
    bbox_px: tuple[int, int, int, int]
    joints_m: np.ndarray


@dataclass
class _TrackState:
    """What the tracker keeps per track id: its descriptor history and its filter."""

    stacker: FrameStacker
    kalman: PoseKalmanFilter
    travel: TravelDirection
    measured: list = field(default_factory=list)    # (55,) filter inputs, for smoothing
    heading_variance: list = field(default_factory=list)   # deg^2 per frame, NaN = model's


class PoseTracker:
    """Tracks every person of a static-camera video (frames fed in order).

    estimator: a PoseEstimator; fps: video frame rate; frame_size: (width, height) pixels;
    max_people: keep at most this many (largest) people per frame, None = all;
    ambiguity_threshold: raw heading norm below which a frame is flagged ambiguous.
    """

    def __init__(self, estimator: PoseEstimator, fps: float, frame_size: tuple[int, int],
                 max_people: int | None = None, ambiguity_threshold: float = 0.5,
                 extractor: SilhouetteExtractor | None = None,
                 associator: Associator | None = None):
        self.estimator = estimator
        self.fps = float(fps)
        self.frame_size = frame_size
        self.max_people = max_people
        self.ambiguity_threshold = ambiguity_threshold
        self.extractor = extractor or SilhouetteExtractor()
        self.associator = associator or Associator()
        self.tracks: dict[int, _TrackState] = {}
        #: Seconds spent per stage so far (silhouettes, association, descriptor, regression,
        #: filter, skeleton), for benchmarks; perf_counter calls cost ~0.1 us each.
        self.stage_seconds: dict[str, float] = defaultdict(float)

    def prime(self, background: np.ndarray) -> None:
        """Learn the empty scene from a background estimate (BGR uint8 (H, W, 3))."""
        self.extractor.prime(background)

    def process(self, frame_index: int, time_s: float, frame: np.ndarray) -> list[TrackedPose]:
        """Track one frame (BGR uint8 (H, W, 3)); returns a pose per person in view."""
        clock = time.perf_counter()
        people = self.extractor(frame)[: self.max_people]
        clock = self._lap("silhouettes", clock)
        matches = self.associator.update(people)
        self._lap("association", clock)
        out = []
        for track_id, person in matches:
            pose = self._pose(track_id, person, frame_index, time_s)
            if pose is not None:
                out.append(pose)
        return out

    def _state(self, track_id: int) -> _TrackState:
        if track_id not in self.tracks:
            kalman = PoseKalmanFilter(self.fps, R=self.estimator.measurement_covariance,
                                      q=self.estimator.process_noise,
                                      ambiguity_threshold=self.ambiguity_threshold)
            self.tracks[track_id] = _TrackState(FrameStacker(self.estimator.stack_depth), kalman,
                                                TravelDirection(self.fps, self.frame_size[0]))
        return self.tracks[track_id]

    def _pose(self, track_id: int, person: PersonMask, frame_index: int,
              time_s: float) -> TrackedPose | None:
        state = self._state(track_id)
        clock = time.perf_counter()
        try:
            descriptor = self.estimator.describe(person.mask)
        except DescriptorSilhouetteError:
            return None                       # a sliver or speck: no pose this frame
        clock = self._lap("descriptor", clock)
        raw = self.estimator.predict(state.stacker.push(descriptor))
        clock = self._lap("regression", clock)
        # While the person walks, the direction of travel picks between front and back views
        # and is fused with the regressor's heading.
        measured, variance = self._with_travel(state, raw, person)
        filtered, ambiguous = state.kalman.step(measured, heading_variance=variance)
        state.measured.append(measured)
        state.heading_variance.append(np.nan if variance is None else variance)
        clock = self._lap("filter", clock)
        w, h = self.frame_size
        ground = ground_position_from_image(person.centroid, person.bbox[3], w, h)
        joints = pose_joints_m(filtered[None], root_position_m=ground[None])[0]
        self._lap("skeleton", clock)
        return TrackedPose(frame_index, time_s, track_id, raw, filtered, ambiguous,
                           person.centroid, person.bbox, joints)


    @staticmethod
    def _with_travel(state: _TrackState, raw: np.ndarray, person: PersonMask):
        """(filter input (55,), its heading variance deg^2 or None) from the raw pose and the
        direction of travel, if the person is moving."""
        travel = state.travel.push(person.centroid[0], person.bbox[3])
        if travel is None:
            return raw, None
        return fuse_heading(resolve_front_back(raw, travel), travel,
                            float(state.kalman.R[0, 0]))

    def _lap(self, stage: str, since: float) -> float:
        now = time.perf_counter()
        self.stage_seconds[stage] += now - since
        return now

    def smoothed_track(self, track_id: int) -> np.ndarray:
        """RTS-smoothed poses (n, 55) of every frame of a track so far (offline use)."""
        state = self.tracks[track_id]
        return state.kalman.rts_smooth(np.array(state.measured),
                                       heading_variance=np.array(state.heading_variance))
