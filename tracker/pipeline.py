"""The per-frame tracking: frame -> people -> track ids -> pose per track, filtered. The regressor
is a PoseEstimator; front/back is decided per track by hypotheses.FrontBackTracker."""
from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from regressor.angles import N_ANGLES
from regressor.edges import SilhouetteError
from regressor.estimator import PoseEstimator
from regressor.stacking import FrameStacker, stack_step
from tracker.tracks.association import MAX_OCCLUDED_S, Associator
from tracker.tracks.filtering import PoseKalmanFilter
from tracker.tracks.hypotheses import (DEFAULT_EXPERTS, FrontBackTracker, canonical_priors,
                                       chain_options, hypotheses_from)
from tracker.tracks.mirror_limbs import sees_mirror
from tracker.video.silhouettes import DEFAULT_MIN_AREA_FRACTION, PersonMask, SilhouetteExtractor
from tracker.tracks.root_path import RootHistory, smoothed_roots
from tracker.outputs.geometry import ground_position_from_image, is_unfamiliar, pose_joints_m
from tracker.video.decode import ASSUMED_FOV_DEG, colourless, focal_length_px

#: The body angles' R scale: only the white part of the regressor's error (docs/tuning.md).
LIMB_R_SCALE = 0.1
#: Heading q scale: the model's q, set by a few training pirouettes, followed misreadings.
HEADING_Q_SCALE = 0.01
#: The joints' R inflation on ambiguous frames: the main head averages a silhouette's two
#: bodies there; a model that gives canonical pairs (one body per frame) needs less.
AMBIGUOUS_JOINT_FACTOR, CANONICAL_AMBIGUOUS_JOINT_FACTOR = 4.0, 2.0


@dataclass(frozen=True)
class TrackerSettings:
    """The tracker's run-time choices (why each default: docs/tuning.md)."""

    max_people: int | None = None       # at most this many (largest) people a frame; None: all
    ambiguity_threshold: float | None = None    # raw heading norm of ambiguity; None: model's
    ambiguous_heading_factor: float = 25.0      # heading's R inflation on ambiguous frames
    ambiguous_joint_factor: float | None = None     # joints' (None: joint_factor's)
    r_scale: float = 1.0                # multiplies the model's measurement covariance R
    q_scale: float = 1.0                # multiplies the model's process noise q
    heading_q_scale: float = HEADING_Q_SCALE    # further multiplies the heading's q
    limb_r_scale: float = LIMB_R_SCALE  # further multiplies the body angles' filter's R
    roll_deg: float = 0.0               # the camera's roll, degrees clockwise
    background_samples: int = 25        # frames spread over the video for the median background
    fov_deg: float = ASSUMED_FOV_DEG    # horizontal field of view for the focal length
    keep_history: bool = True   # keep filter inputs to smooth (~0.6 KB per person and frame)
    novelty: bool = True        # give each pose the estimator's novelty (NaN if it cannot tell)
    trust_zone_foreground: bool = False  # zone's foreground sure person (else colour decides)
    mirror_limbs: bool = True   # average the limbs with the mirror image's (tracks.mirror_limbs)
    min_area_fraction: float = DEFAULT_MIN_AREA_FRACTION  # smallest person, fraction of image

    def threshold(self, estimator: PoseEstimator) -> float:
        """The ambiguity threshold in use: this setting, else the estimator's own."""
        return (estimator.ambiguity_threshold if self.ambiguity_threshold is None
                else self.ambiguity_threshold)

    def joint_factor(self, estimator: PoseEstimator) -> float:
        """The joints' R inflation on ambiguous frames: this setting, else the estimator's."""
        if self.ambiguous_joint_factor is not None:
            return self.ambiguous_joint_factor
        return (CANONICAL_AMBIGUOUS_JOINT_FACTOR if estimator.gives_canonical_pairs
                else AMBIGUOUS_JOINT_FACTOR)


#: fps -> a new per-track filter with PoseKalmanFilter's step, log_likelihoods, copy and
#: rts_smooth (the body angles' filter needs only step and rts_smooth).
FilterFactory = Callable[[float], PoseKalmanFilter]


def kalman_factory(estimator: PoseEstimator, settings: TrackerSettings = TrackerSettings()
                   ) -> Callable[[float], PoseKalmanFilter]:
    """The default filter factory: the estimator's noise models as the settings scale them."""
    q = np.broadcast_to(np.asarray(estimator.process_noise, float) * settings.q_scale,
                        (N_ANGLES,)).copy()
    q[0] *= settings.heading_q_scale
    return partial(PoseKalmanFilter, R=estimator.measurement_covariance * settings.r_scale, q=q,
                   ambiguity_threshold=settings.threshold(estimator),
                   ambiguous_heading_factor=settings.ambiguous_heading_factor,
                   ambiguous_joint_factor=settings.joint_factor(estimator))


def filter_factories(estimator: PoseEstimator, settings: TrackerSettings = TrackerSettings(),
                     filter_factory: FilterFactory | None = None
                     ) -> tuple[FilterFactory, FilterFactory | None]:
    """(front/back hypotheses' filter factory, body angles' or None): None with a custom one,
    and for a model fitted on canonical members (its raw limbs may be the other body's)."""
    if filter_factory is not None:
        return filter_factory, None
    limbs = (None if estimator.canonical_direction is not None else kalman_factory(
        estimator, replace(settings, r_scale=settings.r_scale * settings.limb_r_scale)))
    return kalman_factory(estimator, settings), limbs


@dataclass
class TrackedPose:
    """One person in one frame: what every sink is given."""

    frame_index: int
    time_s: float
    track_id: int
    raw: np.ndarray             # (55,) pose vector, degrees, the heading as (cos, sin)
    filtered: np.ndarray        # (55,) the same, filtered
    ambiguous: bool             # raw heading norm below the ambiguity threshold
    joints_m: np.ndarray        # (18, 3) metres, Y up, root on an approximate ground position
    centroid_px: tuple[float, float] | None = None      # (x, y) px
    bbox_px: tuple[int, int, int, int] | None = None    # (x, y, w, h) px
    runner_up: np.ndarray | None = None     # (55,) the next front/back hypothesis's, if close,
    runner_up_probability: float | None = None      # and its probability
    novelty: float | None = None    # unlike the training silhouettes (PoseEstimates.novelty)

    @property
    def unfamiliar(self) -> bool:
        """Whether the frame's silhouette is unlike the training ones (is_unfamiliar)."""
        return is_unfamiliar(self.novelty)


@dataclass
class _TrackState:
    """Per track id: its descriptor histories and its front/back hypotheses."""

    stacker: FrameStacker
    hypotheses: FrontBackTracker
    mirror_stacker: FrameStacker | None = None      # the mirror images' (mirror_limbs only)
    frames: int = 0                                  # frames with a pose


def default_extractor(settings: TrackerSettings, **options) -> SilhouetteExtractor:
    """PoseTracker's SilhouetteExtractor: the settings' zone rule and smallest person."""
    return SilhouetteExtractor(trust_zone_foreground=settings.trust_zone_foreground,
                               min_area_fraction=settings.min_area_fraction, **options)


@contextmanager
def timed(stages: dict[str, float], stage: str) -> Iterator[None]:
    """Add the block's wall time, seconds, to stages[stage] (PoseTracker.stage_seconds)."""
    clock = time.perf_counter()
    try:
        yield
    finally:
        stages[stage] += time.perf_counter() - clock


#: A person's descriptor (D,) and its mirror image's (D,) or None: PoseTracker.describe.
Description = tuple[np.ndarray, "np.ndarray | None"]


class PoseTracker:
    """Tracks every person of a static-camera video (frames fed in order; filter_factories)."""

    def __init__(self, estimator: PoseEstimator, fps: float,
                 settings: TrackerSettings = TrackerSettings(),
                 extractor: SilhouetteExtractor | None = None,
                 associator: Associator | None = None,
                 filter_factory: FilterFactory | None = None):
        self.estimator = estimator
        self.fps = float(fps)
        self.settings = settings
        self.extractor = extractor or default_extractor(settings)
        self._default_extractor = extractor is None
        self.associator = associator or Associator(
            max_occluded=max(1, round(MAX_OCCLUDED_S * self.fps)))
        self.filter_factory, self.limb_filter_factory = filter_factories(estimator, settings,
                                                                         filter_factory)
        self._mirror = sees_mirror(estimator, settings.mirror_limbs)
        self.stack_step = stack_step(self.fps, estimator.training_fps)  # as apart as in training
        self.frame_shape: tuple[int, int] | None = None      # (height, width) pixels
        self._focal_px = 0.0
        self.tracks: dict[int, _TrackState] = {}
        self.roots = RootHistory()          # each pose's root as placed, by track (keep_history)
        self.people: dict[int, PersonMask] = {}     # by track id, of the last frame (drawing)
        self.stage_seconds: dict[str, float] = defaultdict(float)   # seconds, for benchmarks

    def prime(self, background: np.ndarray, frame_size: tuple[int, int] | None = None) -> None:
        """Learn the empty scene from a background (BGR uint8 (H, W, 3)) at the frames' size,
        or at the extractor's working size for frames of ``frame_size`` (width, height) px."""
        if self._default_extractor and colourless(background):
            # Without colour MOG2 calls every darker pixel shadow, cutting a person to pieces.
            self.extractor = default_extractor(self.settings, detect_shadows=False)
        width, height = frame_size or background.shape[1::-1]
        self._set_frame_shape((height, width))
        self.extractor.prime(background, frame_size=frame_size)

    def _set_frame_shape(self, shape: tuple[int, int]) -> None:
        """Remember the frames' (height, width) px, and the focal length it implies, once."""
        if self.frame_shape is None:
            self.frame_shape = (int(shape[0]), int(shape[1]))
            self._focal_px = focal_length_px(self.frame_shape[1], self.settings.fov_deg)

    def find_people(self, frame: np.ndarray) -> list[PersonMask]:
        """The people in one frame (BGR uint8 (H, W, 3)) of a video fed in order."""
        self._set_frame_shape(frame.shape[:2])
        with timed(self.stage_seconds, "silhouettes"):
            return self.extractor(frame)[: self.settings.max_people]

    def describe(self, person: PersonMask) -> Description | None:
        """A person's upright silhouette descriptor (D,) and its mirror image's (D,) or None;
        None for a sliver. Needs only the mask and the settings (tracker.frame_worker)."""
        with timed(self.stage_seconds, "descriptor"):
            mask = person.mask
            if self.settings.roll_deg:
                from tracker.video.roll import upright_mask    # only --roll needs it
                mask = upright_mask(mask, self.settings.roll_deg)
            try:
                if self._mirror:
                    return self.estimator.describe_with_mirror(mask)
                return self.estimator.describe(mask), None
            except SilhouetteError:
                return None

    def track_frames(self, frames: Sequence[tuple]) -> list[tuple[list[TrackedPose], dict]]:
        """The poses of consecutive frames, each (frame_index, time_s, people (find_people's),
        descriptions (describe()'s, or None: made here)): per frame (its poses, its people by
        track id). The poses are regressed in one batch (the same to ~1e-5 degrees)."""
        rows, people_by_frame = [], []
        for slot, (frame_index, time_s, people, descriptions) in enumerate(frames):
            with timed(self.stage_seconds, "association"):
                matches = self.associator.update(people)
            people_by_frame.append(dict(matches))
            known = ({} if descriptions is None
                     else {id(person): d for person, d in zip(people, descriptions, strict=True)})
            for track_id, person in matches:
                state = self._state(track_id)   # a track exists from its first match
                # A part of a split blob (tracker.video.blob_split) is described here.
                description = (known[id(person)] if id(person) in known
                               else self.describe(person))
                if description is not None:
                    rows.append((slot, track_id, person) + self._stack(state, description))
        if frames:
            self.people = people_by_frame[-1]
        poses: list[list[TrackedPose]] = [[] for _ in frames]
        if rows:
            hypotheses, novelty = self._regress([r[3] for r in rows], [r[4] for r in rows])
            decisions = [self._decide(track_id, person, h)
                         for (_, track_id, person, _, _), h in zip(rows, hypotheses)]
            joints = self._skeletons(decisions, [r[2] for r in rows])
            for (slot, track_id, person, _, _), h, n, d, j in zip(rows, hypotheses, novelty,
                                                                  decisions, joints):
                frame_index, time_s = frames[slot][:2]
                pose = TrackedPose(frame_index, time_s, track_id, h.raw, d.filtered, d.ambiguous,
                                   j, person.centroid, person.bbox, d.runner_up,
                                   d.runner_up_probability, n)
                if self.settings.keep_history:
                    self.roots.add(track_id, frame_index, j[0])
                poses[slot].append(pose)
        return list(zip(poses, people_by_frame))

    def _state(self, track_id: int) -> _TrackState:
        if track_id not in self.tracks:
            depth, step = self.estimator.stack_depth, self.stack_step
            chain = FrontBackTracker(self.filter_factory, self.fps,      # as front_back_tracker's
                                     **chain_options(self.estimator),
                                     keep_history=self.settings.keep_history,
                                     limb_filter_factory=self.limb_filter_factory)
            self.tracks[track_id] = _TrackState(FrameStacker(depth, step), chain,
                                                FrameStacker(depth, step) if self._mirror else None)
        return self.tracks[track_id]

    def _stack(self, state: _TrackState, description: Description
               ) -> tuple[np.ndarray, np.ndarray | None]:
        """The track's stacked descriptor (k*D,) and its mirror images' (or None)."""
        with timed(self.stage_seconds, "regression"):
            descriptor, mirrored = description
            if mirrored is not None:
                mirrored = state.mirror_stacker.push(mirrored)
            return state.stacker.push(descriptor), mirrored

    def _regress(self, stacked: list[np.ndarray], mirrored: list[np.ndarray | None]
                 ) -> tuple[list, list[float | None]]:
        """The hypotheses and novelty of stacked descriptors (each (k*D,)), in one batch."""
        with timed(self.stage_seconds, "regression"):
            X = np.asarray(stacked, dtype=np.float64)
            X_mirror = None if mirrored[0] is None else np.asarray(mirrored, dtype=np.float64)
            estimates = self.estimator.hypotheses(X, DEFAULT_EXPERTS, mirrored=X_mirror,
                                                  novelty=self.settings.novelty)
            novelty = ([float(v) for v in estimates.novelty] if self.settings.novelty
                       else [None] * len(X))
            return hypotheses_from(estimates, canonical_priors(self.estimator)), novelty

    def _decide(self, track_id: int, person: PersonMask, hypotheses):
        """A track's front/back decision (hypotheses.Decision) for one frame."""
        state = self._state(track_id)
        state.frames += 1
        with timed(self.stage_seconds, "filter"):
            return state.hypotheses.step(hypotheses)

    def _skeletons(self, decisions: list, people: list[PersonMask]) -> np.ndarray:
        """The joints (N, 18, 3) metres of the decisions' filtered poses, on the ground."""
        h, w = self.frame_shape
        with timed(self.stage_seconds, "skeleton"):
            ground = np.array([ground_position_from_image(p.centroid, p.bbox[3], w, h,
                                                          focal_px=self._focal_px)
                               for p in people])
            return pose_joints_m(np.array([d.filtered for d in decisions]),
                                 root_position_m=ground)

    def smoothed_track(self, track_id: int, start: int = 0, stop: int | None = None
                       ) -> np.ndarray:
        """RTS-smoothed poses (n, 55) of a track's poses start..stop-1 (default all) as if they
        were the whole track, on the Viterbi front/back sequence; needs keep_history."""
        if not self.settings.keep_history:
            raise ValueError("smoothed_track needs TrackerSettings(keep_history=True)")
        return self.tracks[track_id].hypotheses.smoothed(start, stop)

    def smoothed_root_path(self, track_id: int, start: int = 0, stop: int | None = None
                           ) -> np.ndarray:
        """The roots (n, 3) metres of a track's poses start..stop-1 (as smoothed_track's),
        the tracker's placements smoothed over time; needs settings.keep_history."""
        if not self.settings.keep_history:
            raise ValueError("smoothed_root_path needs TrackerSettings(keep_history=True)")
        raw, frames = self.roots.get(track_id, start, stop)
        return smoothed_roots(raw, self.fps, frames=frames)
