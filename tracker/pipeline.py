"""The per-frame tracking loop: frame -> people -> track ids -> pose per track, filtered.

Reads like DESIGN.md's data flow, one stage a line (see PoseTracker.process). The regressor side
is an estimator (regressor.estimator.PoseEstimator; regressor.pose_model.PoseModel is one):
describe(mask) -> descriptor, stack_depth, hypotheses(stacked) -> poses, probabilities, limbs,
front probability, novelty; plus the filter's noise models, the ambiguity threshold it was
trained with and its front/back figures. Front/back is decided per track by
tracker.tracks.hypotheses.FrontBackTracker (one filter from the factory per hypothesis). Every stage
is injectable: the silhouette extractor, the associator and the filter factory (norfair's
``filter_factory``).
"""
from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from regressor.angles import N_ANGLES
from regressor.edges import SilhouetteError
from regressor.estimator import PoseEstimator
from regressor.stacking import FrameStacker, stack_step
from tracker.tracks.association import MAX_OCCLUDED_S, Associator
from tracker.video.roll import upright_mask
from tracker.tracks.filtering import PoseKalmanFilter
from tracker.tracks.hypotheses import (DEFAULT_EXPERTS, FrontBackTracker, canonical_priors, chain_options,
                         hypotheses_from)
from tracker.tracks.mirror_limbs import sees_mirror
from tracker.video.silhouettes import DEFAULT_MIN_AREA_FRACTION, PersonMask, SilhouetteExtractor
from tracker.tracks.root_path import RootHistory, smoothed_roots
from tracker.outputs.geometry import ground_position_from_image, is_unfamiliar, pose_joints_m
from tracker.video.decode import ASSUMED_FOV_DEG, colourless, focal_length_px


#: The body angles' filter takes as measurement noise only the white part of the regressor's
#: error (its validation residual is mostly a slow bias): R times this (docs/tuning.md).
LIMB_R_SCALE = 0.1

#: Multiplies the model's heading process noise: the model's q is dominated by a few pirouettes
#: in the training motion, so the filter followed confident misreadings (docs/tuning.md).
HEADING_Q_SCALE = 0.01

#: The joints' R inflation on ambiguous frames: the main head averages a silhouette's two
#: bodies there; a model that gives canonical pairs (one body per frame) needs less.
AMBIGUOUS_JOINT_FACTOR = 4.0
CANONICAL_AMBIGUOUS_JOINT_FACTOR = 2.0


@dataclass(frozen=True)
class TrackerSettings:
    """The tracker's run-time choices, in one place (the ``track`` command, the evaluation and
    the benchmark all build one). Why each default is what it is: docs/tuning.md.

    max_people: keep at most this many (largest) people per frame, None = all.
    ambiguity_threshold: raw heading norm below which a frame is ambiguous; None = the one the
    model was trained with (PoseModel.ambiguity_threshold). ambiguous_heading_factor,
    ambiguous_joint_factor: R inflation on ambiguous frames (PoseKalmanFilter; None for the
    joints = the estimator's, :meth:`joint_factor`). r_scale, q_scale: multiply the model's
    measurement covariance R and process noise q; heading_q_scale further multiplies the
    heading's q. limb_r_scale: further multiplies R for the body angles' filter.
    roll_deg: the camera's roll, degrees clockwise (silhouettes are turned upright first).
    background_samples: frames spread over the video for the median background. fov_deg: the
    horizontal field of view assumed for the focal length. keep_history: keep every track's
    filter inputs for PoseTracker.smoothed_track (about 0.6 KB per person per frame).
    novelty: give each pose the estimator's novelty and count each track's frames above
    UNFAMILIAR_NOVELTY (NaN from a model that cannot tell, None when False).
    trust_zone_foreground: the default extractor takes the subtractor's foreground inside the
    background's unreliable zone as sure person (True) or lets colour decide on it (False).
    min_area_fraction: the default extractor's smallest person, a fraction of the image.
    mirror_limbs: average the limbs with the mirror image's (tracker.tracks.mirror_limbs), for a model
    whose limb networks saw mirror images.
    """

    max_people: int | None = None
    ambiguity_threshold: float | None = None
    ambiguous_heading_factor: float = 25.0
    ambiguous_joint_factor: float | None = None
    r_scale: float = 1.0
    q_scale: float = 1.0
    heading_q_scale: float = HEADING_Q_SCALE
    limb_r_scale: float = LIMB_R_SCALE
    roll_deg: float = 0.0
    background_samples: int = 25
    fov_deg: float = ASSUMED_FOV_DEG
    keep_history: bool = True
    novelty: bool = True
    trust_zone_foreground: bool = False
    mirror_limbs: bool = True
    min_area_fraction: float = DEFAULT_MIN_AREA_FRACTION

    def threshold(self, estimator: PoseEstimator) -> float:
        """The ambiguity threshold in use: this setting, else the estimator's own."""
        if self.ambiguity_threshold is not None:
            return self.ambiguity_threshold
        return estimator.ambiguity_threshold

    def joint_factor(self, estimator: PoseEstimator) -> float:
        """The joints' R inflation on ambiguous frames: this setting, else the estimator's
        (CANONICAL_AMBIGUOUS_JOINT_FACTOR for one that gives canonical pairs,
        AMBIGUOUS_JOINT_FACTOR otherwise)."""
        if self.ambiguous_joint_factor is not None:
            return self.ambiguous_joint_factor
        if estimator.gives_canonical_pairs:
            return CANONICAL_AMBIGUOUS_JOINT_FACTOR
        return AMBIGUOUS_JOINT_FACTOR


def kalman_factory(estimator: PoseEstimator, settings: TrackerSettings = TrackerSettings()
                   ) -> Callable[[float], PoseKalmanFilter]:
    """The default filter factory: fps -> a PoseKalmanFilter with the estimator's noise models
    (scaled by settings.r_scale / q_scale / heading_q_scale) and the settings' ambiguity
    handling."""
    q = np.broadcast_to(np.asarray(estimator.process_noise, float) * settings.q_scale,
                        (N_ANGLES,)).copy()
    q[0] *= settings.heading_q_scale

    kwargs = dict(R=estimator.measurement_covariance * settings.r_scale, q=q,
                  ambiguity_threshold=settings.threshold(estimator),
                  ambiguous_heading_factor=settings.ambiguous_heading_factor,
                  ambiguous_joint_factor=settings.joint_factor(estimator))

    def make(fps: float) -> PoseKalmanFilter:
        return PoseKalmanFilter(fps, **kwargs)
    return make


def limb_kalman_factory(estimator: PoseEstimator, settings: TrackerSettings = TrackerSettings()
                        ) -> Callable[[float], PoseKalmanFilter]:
    """fps -> the PoseKalmanFilter of the output's body angles: kalman_factory's with R
    further scaled by settings.limb_r_scale (LIMB_R_SCALE)."""
    return kalman_factory(estimator, replace(settings,
                                             r_scale=settings.r_scale * settings.limb_r_scale))


def filter_factories(estimator: PoseEstimator, settings: TrackerSettings = TrackerSettings(),
                     filter_factory: Callable[[float], PoseFilter] | None = None,
                     ) -> tuple[Callable[[float], PoseFilter], Callable[[float], PoseFilter] | None]:
    """(the front/back hypotheses' filter factory, the body angles' filter factory) as the
    tracker runs them: kalman_factory and limb_kalman_factory; with a custom filter_factory,
    that factory and None (its filters give the whole pose, no separate limb filter). A model
    fitted on canonical members (PoseModel.canonical_direction) gets no limb filter either: its
    raw limbs may be the other body's, and the chain's choice of member is the limbs' too."""
    if filter_factory is not None:
        return filter_factory, None
    limbs = (None if estimator.canonical_direction is not None
             else limb_kalman_factory(estimator, settings))
    return kalman_factory(estimator, settings), limbs


def front_back_tracker(estimator: PoseEstimator, fps: float,
                       settings: TrackerSettings = TrackerSettings(),
                       filter_factory: Callable[[float], PoseFilter] | None = None,
                       ) -> FrontBackTracker:
    """A track's front/back hypotheses with the filters of filter_factories."""
    return _front_back_chain(estimator, fps, settings,
                             *filter_factories(estimator, settings, filter_factory))


def _front_back_chain(estimator: PoseEstimator, fps: float, settings: TrackerSettings, chain,
                      limbs) -> FrontBackTracker:
    """The one place a track's FrontBackTracker is built: the estimator's switch rates and
    evidence weight, the filter factories chain and limbs (filter_factories)."""
    return FrontBackTracker(chain, fps, **chain_options(estimator),
                            keep_history=settings.keep_history, limb_filter_factory=limbs)


class PoseFilter(Protocol):
    """What the tracker needs of a per-track filter (PoseKalmanFilter is one)."""

    def step(self, raw55: np.ndarray) -> tuple[np.ndarray, bool]: ...
    # (55,) -> (filtered (55,), ambiguous)

    def rts_smooth(self, raws: np.ndarray) -> np.ndarray: ...


@dataclass
class TrackedPose:
    """One person in one frame: what every sink is given. raw/filtered: (55,) pose vectors
    (degrees; heading as cos, sin); ambiguous: raw heading norm below the threshold; joints_m:
    (18, 3) metres, Y up, for drawing (root placed on an approximate ground position from the
    image); centroid_px: (x, y) pixels; bbox_px: (x, y, w, h) pixels (None when unknown);
    runner_up: (55,) the filtered pose of the next most probable front/back hypothesis and
    runner_up_probability, when that is close (tracker.tracks.hypotheses.CLOSE_PROBABILITY), else None;
    novelty: how unlike the training silhouettes the frame's input is (PoseEstimates.novelty; about
    1 % of training rows are above 1), with TrackerSettings(novelty=True), else None."""

    frame_index: int
    time_s: float
    track_id: int
    raw: np.ndarray
    filtered: np.ndarray
    ambiguous: bool
    joints_m: np.ndarray
    centroid_px: tuple[float, float] | None = None
    bbox_px: tuple[int, int, int, int] | None = None
    runner_up: np.ndarray | None = None
    runner_up_probability: float | None = None
    novelty: float | None = None

    @property
    def unfamiliar(self) -> bool:
        """Whether the frame's silhouette is unlike the training ones (novelty above
        regressor.pose_model.UNFAMILIAR_NOVELTY; False when unknown): the sinks' rule,
        tracker.outputs.geometry.is_unfamiliar."""
        return is_unfamiliar(self.novelty)


@dataclass
class _TrackState:
    """What the tracker keeps per track id: its descriptor history and its front/back
    hypotheses (one filter each)."""

    stacker: FrameStacker
    hypotheses: FrontBackTracker
    mirror_stacker: FrameStacker | None = None      # the mirror images' (mirror_limbs only)
    measured: list = field(default_factory=list)    # (55,) raw poses (keep_history only)
    frames: int = 0                                  # frames with a pose
    unfamiliar: int = 0                              # of them, novelty > UNFAMILIAR_NOVELTY


def default_extractor(settings: TrackerSettings, **options) -> SilhouetteExtractor:
    """The silhouette extractor PoseTracker makes when given none: the settings' zone rule and
    smallest person; ``options`` go to SilhouetteExtractor too (e.g. detect_shadows=False)."""
    return SilhouetteExtractor(trust_zone_foreground=settings.trust_zone_foreground,
                               min_area_fraction=settings.min_area_fraction, **options)


#: A person's descriptor (D,) and its mirror image's (D,) or None: PoseTracker.describe.
Description = tuple[np.ndarray, "np.ndarray | None"]


class PoseTracker:
    """Tracks every person of a static-camera video (frames fed in order).

    estimator: a PoseEstimator; fps: video frame rate; settings: TrackerSettings; extractor:
    frame -> people (default SilhouetteExtractor); associator: people -> track ids (default
    Associator, a track hidden in a group for up to MAX_OCCLUDED_S); filter_factory: fps -> a
    PoseFilter per front/back hypothesis of a track (default kalman_factory(estimator,
    settings), with the body angles from limb_kalman_factory's filter; a custom one gives the
    whole pose: filter_factories). The frame size (height, width) is taken from the background
    given to prime() or the first frame. With the default extractor, a colourless
    background (black-and-white video) turns shadow detection off (see prime()).
    """

    def __init__(self, estimator: PoseEstimator, fps: float,
                 settings: TrackerSettings = TrackerSettings(),
                 extractor: SilhouetteExtractor | None = None,
                 associator: Associator | None = None,
                 filter_factory: Callable[[float], PoseFilter] | None = None):
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
        #: Frames between a track's stacked descriptors: a video faster than the model's
        #: training sequences stacks frames as far apart in time as those were.
        self.stack_step = stack_step(self.fps, estimator.training_fps)
        self.frame_shape: tuple[int, int] | None = None      # (height, width) pixels
        self._focal_px = 0.0
        self.tracks: dict[int, _TrackState] = {}
        #: Every pose's root as placed here, by track (keep_history only): the smoothed outputs
        #: draw their bodies at it smoothed (smoothed_root_path), whatever was streamed.
        self.roots = RootHistory()
        #: Track id -> silhouette of each person in the frame processed last (for drawing).
        self.people: dict[int, PersonMask] = {}
        #: Seconds spent per stage so far (silhouettes, association, descriptor, regression,
        #: filter, skeleton), for benchmarks; perf_counter calls cost ~0.1 us each.
        self.stage_seconds: dict[str, float] = defaultdict(float)

    def prime(self, background: np.ndarray, frame_size: tuple[int, int] | None = None) -> None:
        """Learn the empty scene from a background estimate (BGR uint8 (H, W, 3)): at the
        frames' size, or at the extractor's working size for frames of ``frame_size`` (width,
        height) px (SilhouetteExtractor.prime)."""
        if self._default_extractor and colourless(background):
            # MOG2 calls a pixel shadow when it is a darker shade of the background's colour;
            # without colour every darker pixel is, and a person darker than the scene is cut
            # into pieces (the sample walk in gray: 11 tracks instead of 1).
            self.extractor = default_extractor(self.settings, detect_shadows=False)
        if frame_size is None:
            self._set_frame_shape(background.shape[:2])
            self.extractor.prime(background)
        else:
            self._set_frame_shape((frame_size[1], frame_size[0]))
            self.extractor.prime(background, frame_size=frame_size)

    def _set_frame_shape(self, shape: tuple[int, int]) -> None:
        """Remember the frames' (height, width) px, and the focal length it implies, once."""
        if self.frame_shape is None:
            self.frame_shape = (int(shape[0]), int(shape[1]))
            self._focal_px = focal_length_px(self.frame_shape[1], self.settings.fov_deg)

    def process(self, frame_index: int, time_s: float, frame: np.ndarray) -> list[TrackedPose]:
        """Track one frame (BGR uint8 (H, W, 3)); returns a pose per person in view."""
        return self.track_people(frame_index, time_s, self.find_people(frame))

    def find_people(self, frame: np.ndarray) -> list[PersonMask]:
        """The first half of :meth:`process`: the people in one frame (BGR uint8 (H, W, 3)),
        at most settings.max_people. Frames go in order (the background model learns)."""
        self._set_frame_shape(frame.shape[:2])
        clock = time.perf_counter()
        people = self.extractor(frame)[: self.settings.max_people]
        self._lap("silhouettes", clock)
        return people

    def describe(self, person: PersonMask) -> Description | None:
        """A person's silhouette descriptor (D,) and, when the tracker averages mirror images
        (tracker.tracks.mirror_limbs), its mirror image's (D,) (else None), made upright by the
        settings' roll; None for a sliver or speck that has no descriptor. Depends on nothing
        but the mask and the settings, so it can run apart from the tracking (tracker.frame_worker)."""
        clock = time.perf_counter()
        mask = upright_mask(person.mask, self.settings.roll_deg)
        try:
            if self._mirror:
                description = self.estimator.describe_with_mirror(mask)
            else:
                description = (self.estimator.describe(mask), None)
        except SilhouetteError:
            description = None
        self._lap("descriptor", clock)
        return description

    def track_people(self, frame_index: int, time_s: float, people: Sequence[PersonMask],
                     descriptions: Sequence[Description | None] | None = None
                     ) -> list[TrackedPose]:
        """The second half of :meth:`process`: the poses of one frame's people (from
        :meth:`find_people`, in order). descriptions: :meth:`describe` of each person, when
        made elsewhere; None: described here (only the people on confirmed tracks)."""
        return self.track_frames([(frame_index, time_s, people, descriptions)])[0][0]

    def track_frames(self, frames: Sequence[tuple]) -> list[tuple[list[TrackedPose], dict]]:
        """:meth:`track_people` for several consecutive frames at once: frames is a sequence
        of (frame_index, time_s, people, descriptions) as its arguments. Returns per frame
        (its poses, its people by track id). Every pose is regressed in one batch: the
        weights (~11 MB) are read once for all, which at 8 frames a batch costs a quarter of
        what 8 one-frame calls do (scripts/bench_track.py); the results equal one-frame calls'
        to ~1e-5 degrees (the sums' rounding). Association, the filters and the skeleton
        still go frame by frame, in order: the same tracks and decisions."""
        rows, people_by_frame = [], []
        for slot, (frame_index, time_s, people, descriptions) in enumerate(frames):
            clock = time.perf_counter()
            matches = self.associator.update(people)
            people_by_frame.append(dict(matches))
            self._lap("association", clock)
            known = ({} if descriptions is None
                     else {id(person): d for person, d in zip(people, descriptions, strict=True)})
            for track_id, person in matches:
                state = self._state(track_id)   # a track exists from its first match
                # A part of a split blob (tracker.video.blob_split) was made here: described here.
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
                self.tracks[track_id].unfamiliar += pose.unfamiliar
                if self.settings.keep_history:
                    self.roots.add(track_id, frame_index, j[0])
                poses[slot].append(pose)
        return list(zip(poses, people_by_frame))

    def _state(self, track_id: int) -> _TrackState:
        if track_id not in self.tracks:
            step = self.stack_step
            self.tracks[track_id] = _TrackState(
                FrameStacker(self.estimator.stack_depth, step),
                _front_back_chain(self.estimator, self.fps, self.settings, self.filter_factory,
                                  self.limb_filter_factory),
                FrameStacker(self.estimator.stack_depth, step) if self._mirror else None)
        return self.tracks[track_id]

    def _stack(self, state: _TrackState, description: Description
               ) -> tuple[np.ndarray, np.ndarray | None]:
        """The track's stacked descriptor (k*D,) and its mirror images' (or None)."""
        clock = time.perf_counter()
        descriptor, mirrored = description
        stacked = state.stacker.push(descriptor)
        if mirrored is not None:
            mirrored = state.mirror_stacker.push(mirrored)
        self._lap("regression", clock)
        return stacked, mirrored

    def _regress(self, stacked: list[np.ndarray], mirrored: list[np.ndarray | None]
                 ) -> tuple[list, list[float | None]]:
        """The hypotheses and novelty of stacked descriptors (each (k*D,)), in one batch."""
        clock = time.perf_counter()
        X = np.asarray(stacked, dtype=np.float64)
        X_mirror = None if mirrored[0] is None else np.asarray(mirrored, dtype=np.float64)
        estimates = self.estimator.hypotheses(X, DEFAULT_EXPERTS, mirrored=X_mirror,
                                              novelty=self.settings.novelty)
        hypotheses = hypotheses_from(estimates, canonical_priors(self.estimator))
        novelty = ([float(v) for v in estimates.novelty] if self.settings.novelty
                   else [None] * len(X))
        self._lap("regression", clock)
        return hypotheses, novelty

    def _decide(self, track_id: int, person: PersonMask, hypotheses):
        """A track's front/back decision (tracker.tracks.hypotheses.Decision) for one frame from its
        hypotheses."""
        state = self._state(track_id)
        clock = time.perf_counter()
        decision = state.hypotheses.step(hypotheses)
        state.frames += 1
        if self.settings.keep_history:
            state.measured.append(hypotheses.raw)
        self._lap("filter", clock)
        return decision

    def _skeletons(self, decisions: list, people: list[PersonMask]) -> np.ndarray:
        """The joints (N, 18, 3) metres of the decisions' filtered poses, each placed on its
        person's approximate ground position, all in one forward-kinematics call (it costs
        about as much for a batch as for one pose)."""
        clock = time.perf_counter()
        h, w = self.frame_shape
        ground = np.array([ground_position_from_image(p.centroid, p.bbox[3], w, h,
                                                      focal_px=self._focal_px) for p in people])
        joints = pose_joints_m(np.array([d.filtered for d in decisions]), root_position_m=ground)
        self._lap("skeleton", clock)
        return joints

    def _lap(self, stage: str, since: float) -> float:
        now = time.perf_counter()
        self.stage_seconds[stage] += now - since
        return now

    def smoothed_track(self, track_id: int, start: int = 0, stop: int | None = None
                       ) -> np.ndarray:
        """RTS-smoothed poses (n, 55) of every frame of a track so far (needs
        settings.keep_history), on the most probable (Viterbi) sequence of front/back
        hypotheses; with start/stop, of the track's poses start..stop-1 (counted from its
        first pose) smoothed as if the track were those alone (tracker.tracks.fixed_lag)."""
        if not self.settings.keep_history:
            raise ValueError("smoothed_track needs TrackerSettings(keep_history=True)")
        return self.tracks[track_id].hypotheses.smoothed(start, stop)

    def smoothed_root_path(self, track_id: int, start: int = 0, stop: int | None = None
                           ) -> np.ndarray:
        """The roots (n, 3) metres of a track's poses start..stop-1 (as smoothed_track's),
        the tracker's own placements smoothed over the video's time (tracker.tracks.root_path); needs
        settings.keep_history."""
        if not self.settings.keep_history:
            raise ValueError("smoothed_root_path needs TrackerSettings(keep_history=True)")
        raw, frames = self.roots.get(track_id, start, stop)
        return smoothed_roots(raw, self.fps, frames=frames)
