"""The per-frame tracking loop: frame -> people -> track ids -> pose per track, filtered.

Reads like DESIGN.md's data flow, one stage a line (see PoseTracker.process). The regressor side
is an estimator object (regressor.pose_model.PoseModel) with three things: describe(mask) ->
descriptor, stack_depth, predict(stacked) -> raw 55-D pose (or, for a mixture of experts,
predict_hypotheses(stacked, m) -> (poses (m, 55), probabilities (m,))); plus the filter's noise
models and the ambiguity threshold it was trained with. Front/back is decided per track by
tracker.hypotheses.FrontBackTracker (one filter from the factory per hypothesis). Every stage
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
from regressor.pose_model import training_fps_of
from regressor.stacking import FrameStacker, stack_step
from .association import MAX_OCCLUDED_S, Associator
from .roll import upright_mask
from .filtering import PoseKalmanFilter
from .imm_filter import DEFAULT_SWITCH, TURN_AND_STOP, HeadingModel, IMMPoseFilter
from .hypotheses import FrontBackTracker, chain_options, propose_batch
from .mirror_limbs import sees_mirror
from .silhouettes import DEFAULT_MIN_AREA_FRACTION, PersonMask, SilhouetteExtractor
from .root_path import RootHistory, smoothed_roots
from .sinks.geometry import ground_position_from_image, is_unfamiliar, pose_joints_m
from .travel import TravelDirection
from .video import ASSUMED_FOV_DEG, colourless, focal_length_px


#: The body angles' filter (tracker.hypotheses, "Limbs") takes as measurement noise only the
#: white part of the regressor's error. The model's R is the covariance of its whole validation
#: residual, but that residual is mostly a slow bias (the same pose misread for many frames):
#: half the variance of its frame-to-frame change is 7.5 % of its variance on the validation
#: renders (10-13 % on track's inputs from five spiral-walk videos), and a filter that takes
#: the bias for white noise lags the gait. Chosen on the 28 validation renders of
#: scripts/learn_hypothesis_priors.py (6 validation trials and 07_12, spiral and fixed camera,
#: as recorded and reversed; heading from the chain in every case), mean over renders of the
#: 53 body angles' error / correlation of the 8 most-moving angles / mean |second difference|
#: (jitter, deg): chain's own limbs 9.197 / 0.185 / 1.20; this filter with limb_r_scale 1.0:
#: 9.064 / 0.244 / 0.96, 0.3: 9.044 / 0.261 / 1.16, 0.1: 9.043 / 0.269 / 1.34, 0.05: 9.044 /
#: 0.271 / 1.46; the raw poses 9.005 / 0.266 / 2.28 (2026-12-01, a one-off driver). 0.1: as
#: accurate as the raw poses with 40 % less jitter. Re-checked 2026-12-02 with the side
#: classifier and the joints' inflation 2 (same renders, corr8 filtered / smoothed): 0.05
#: 0.545 / 0.604, 0.1 0.546 / 0.609, 0.2 0.545 / 0.612, 0.4 0.540 / 0.608 (heading unchanged).
#: Also tried then: this filter's process noise as the full covariance of the training poses'
#: angular accelerations (joints coupled, as in a gait) instead of per angle: 0.548 / 0.607.
#: Tried and not adopted (2026-12-02, one-off driver): a gain per body angle on the filtered
#: output about the training-mean pose, fitted on the five validation videos through
#: ``track`` (least squares of the truth on the output), since on the walks some angles swing
#: at a fraction of the truth's amplitude (the arms at about a third). Over all angles pooled
#: the output is not shrunk (one gain for all: 1.02); per angle, leave-one-video-out, it
#: made the 53 angles' error worse (7.69 -> 8.09 deg; half-way to 1: 7.74; with an offset
#: too: 8.65) for a flexion error 15.9 -> 15.2; corr8 is unchanged by any gain. The output
#: also does not lag the truth: its corr8 peaks at a lag of 0-1 frame (16_11 0.763 at 0, 02_02
#: 0.706 at 1 against 0.698 at 0, 08_03 0.786 against 0.784).
LIMB_R_SCALE = 0.1

#: Multiplies the model's heading process noise (q[0]) in every filter. The model's q is the
#: acceleration variance of the training poses, and for the heading it is dominated by a few
#: pirouettes (one dance trial, 05_16, gives half of it; a robust (MAD) estimate is 0.16 of it),
#: so the filter follows the regressor when it confidently misreads the heading for a few
#: frames: on the shipped sample, frames 126-142, the raw heading swings 140 degrees in 10 frames
#: from a back view to a front view, and the filter went along. Chosen on the 28 validation
#: renders (as LIMB_R_SCALE; mean filtered heading RMS, deg) with q scaled by 1 / 0.3 / 0.1 /
#: 0.03 / 0.01 / 0.003: 70.8 / 68.3 / 67.0 / 64.4 / 61.9 / 65.4; through ``track`` on the five
#: validation spiral videos (02_02, 08_03, 05_02, 09_04, 02_05) by 1 / 0.1 / 0.01 / 0.003 /
#: 0.001: 37.0 / 34.7 / 30.9 / 28.8 / 30.7, their corr8 unchanged (0.357). 2026-12-01.
HEADING_Q_SCALE = 0.01

#: The front/back chain's filters follow the heading with two models mixed as an IMM
#: (tracker.imm_filter): constant velocity, and one that forgets the heading's rate over 0.3 s,
#: switching with probability 0.01 a frame at 30 fps. With one constant-velocity model and the
#: small heading noise above, a turn's rate persists after the turn stops (a synthetic 90-degree
#: turn: 16 degrees past it, 12 with these; tests/test_imm_filter.py). Chosen on validation
#: data, 2026-12-04 (one-off drivers; mean filtered heading RMS, deg, and the share of frames
#: within 90 degrees of the truth): 28 renders (see LIMB_R_SCALE) 32.1 / 84.8 % with one model,
#: 30.3 / 86.3 % with these (a rate-forgetting time of 0.1-0.5 s, a switch of 0.003-0.05 and
#: the second model's noise x0.3-3 all gave 30.3-31.7; a third model with 100x the heading
#: noise, or that one instead, 30.6-31.7 but flipped front/back on two videos); through
#: ``track`` on 12 validation videos (five trials spiral and fixed, 06_10 and 07_12 fixed)
#: 36.7 / 89.2 % -> 31.5 / 93.5 %, smoothed 29.2 -> 23.2, corr8 0.444 -> 0.446. The price is a
#: steady turn's lag: 02_02 spiral 9.0 -> 10.1, 09_04 spiral 8.1 -> 9.0. A single filter that
#: forgets the rate (stop 38) gave 36.5-33.7 on the videos with 02_02 spiral at 9.3-10.8.
#: () or one model: the plain constant-velocity filter.
HEADING_MODELS: tuple = TURN_AND_STOP
HEADING_SWITCH = DEFAULT_SWITCH

#: The joints' R inflation on ambiguous frames (PoseKalmanFilter's ambiguous_joint_factor).
#: The main head averages a silhouette's two bodies where it cannot tell them apart, so its
#: limbs on such frames are worth less (AMBIGUOUS_JOINT_FACTOR). A model that gives canonical
#: pairs (tracker.hypotheses, "Canonical hypotheses") measures the limb networks' member, which
#: commits to one body on those frames too: its inflation is smaller. Chosen on the 28
#: validation renders (one-off driver over the real chain; mean filtered / smoothed heading
#: RMS, deg, and corr8 of the 8 most-moving angles, filtered) with factor 1 / 1.5 / 2 / 3 / 4:
#: 33.8 / 32.7 / 32.7 / 35.7 / 36.1, smoothed 28.2 / 27.4 / 26.6 / 27.0 / 27.8, corr8 0.546 /
#: 0.547 / 0.546 / 0.541 / 0.541; through ``track`` on the five validation videos (02_02 /
#: 08_03 / 05_02 / 09_04 / 02_05) factor 2 against 4: filtered heading 8.1 / 8.0 / 47.3 /
#: 14.7 / 68.4 against 8.1 / 8.0 / 56.3 / 19.5 / 68.4 (smoothed mean 27.7 against 31.1), corr8
#: mean 0.438 against 0.440 (2026-12-02). Where the main head's frames are rarely ambiguous
#: (the walks 02_02, 08_03) nothing changes.
AMBIGUOUS_JOINT_FACTOR = 4.0
CANONICAL_AMBIGUOUS_JOINT_FACTOR = 2.0


@dataclass(frozen=True)
class TrackerSettings:
    """The tracker's run-time choices, in one place (the ``track`` command, the evaluation and
    the benchmark all build one).

    max_people: keep at most this many (largest) people per frame, None = all.
    ambiguity_threshold: raw heading norm below which a frame is ambiguous; None = the one the
    model was trained with (PoseModel.ambiguity_threshold). ambiguous_heading_factor,
    ambiguous_joint_factor: R inflation on ambiguous frames (PoseKalmanFilter; None for the
    joints = the estimator's (:meth:`joint_factor`); with the front/back
    chain the heading's inflation makes a 180-degree jump cheap for its filters, but lowering it
    did not help on validation: factor 25 / 4 / 1 gave mean filtered heading 59.5 / 51.2 / 56.1
    degrees on the 28 validation renders, 28.0 / 32.3 / 30.3 on the five validation videos,
    2026-12-02). r_scale, q_scale:
    multiply the model's measurement covariance R and process noise q; heading_q_scale further
    multiplies the heading's q (HEADING_Q_SCALE). heading_models, heading_switch: the IMM
    heading models of the front/back chain's filters and their switch probability per frame at
    30 fps (HEADING_MODELS; one or none: a plain PoseKalmanFilter). limb_r_scale: further
    multiplies R for the filter of the output's body angles (LIMB_R_SCALE, limb_kalman_factory);
    roll_deg: the camera's roll (tracker.roll.upright_mask: how far the scene's vertical leans
    clockwise in the image, degrees); silhouettes are turned upright before they are described.
    background_samples:
    frames spread over the video for the median background. fov_deg: the horizontal field of
    view assumed for the focal length (direction of travel, ground position). keep_history:
    keep every track's filter inputs for PoseTracker.smoothed_track (about 0.6 KB per person
    per frame, so memory grows with the video); ``track`` keeps them only to smooth a JSON,
    BVH or MCAP output (its default; not with --no-smooth).
    novelty: give each pose the estimator's novelty (PoseModel.novelty: how unlike the
    training silhouettes its input is), and count each track's frames above
    UNFAMILIAR_NOVELTY. For the shipped model it reuses the heading index's nearest
    neighbours of the frame, so it costs little per frame; the index's typical distance comes
    from the model file (an older file's is computed once, about 0.35 s, when the tracker is
    made). An estimator without ``novelty`` gives None. trust_zone_foreground: whether the
    default extractor takes the subtractor's foreground inside the background's unreliable
    zone (a person who stays in one place) as sure person (``track --zone-foreground sure``);
    False, the default since 2026-12-04, lets colour decide on it too
    (tracker.silhouettes.refine_in_zone: fewer ghosts, some lost limb pixels). Chosen on the 12
    validation videos through track's loop (two walks, a dance, a run and punches as spirals
    and from a fixed camera, two more trials from a fixed camera): filtered err53 / corr8 /
    heading RMS 8.242 / 0.447 / 31.41 with the sure rule, 7.311 / 0.563 / 31.63 with colour;
    smoothed 8.103 / 0.475 / 23.18 and 7.013 / 0.618 / 23.22 (the fixed-camera clips gain: a
    short clip's walker stays in one region, which becomes the zone; the spirals do not
    change). An extractor given to PoseTracker keeps its own rule.
    min_area_fraction: the default extractor's smallest person, as a fraction of the image
    (tracker.silhouettes.DEFAULT_MIN_AREA_FRACTION; ``track --min-area``).
    mirror_limbs: average the limbs with the model's limbs for each frame's mirror image, for
    a model whose limb networks were fitted on mirror images (tracker.mirror_limbs; costs a
    second descriptor histogram and network pass per person and frame); other estimators
    ignore it. travel_offset_memory: each track keeps its own belief over (facing - direction
    of travel), carried over time (FrontBackTracker.offset_memory); False: the population's
    prior on every frame.
    """

    max_people: int | None = None
    ambiguity_threshold: float | None = None
    ambiguous_heading_factor: float = 25.0
    ambiguous_joint_factor: float | None = None
    r_scale: float = 1.0
    q_scale: float = 1.0
    heading_q_scale: float = HEADING_Q_SCALE
    heading_models: tuple[HeadingModel, ...] = HEADING_MODELS
    heading_switch: float = HEADING_SWITCH
    limb_r_scale: float = LIMB_R_SCALE
    roll_deg: float = 0.0
    background_samples: int = 25
    fov_deg: float = ASSUMED_FOV_DEG
    keep_history: bool = True
    novelty: bool = True
    trust_zone_foreground: bool = False
    mirror_limbs: bool = True
    travel_offset_memory: bool = True
    min_area_fraction: float = DEFAULT_MIN_AREA_FRACTION

    def threshold(self, estimator) -> float:
        """The ambiguity threshold in use: this setting, else the estimator's own."""
        if self.ambiguity_threshold is not None:
            return self.ambiguity_threshold
        return estimator.ambiguity_threshold

    def joint_factor(self, estimator) -> float:
        """The joints' R inflation on ambiguous frames: this setting, else the estimator's
        (CANONICAL_AMBIGUOUS_JOINT_FACTOR for one that gives canonical pairs,
        AMBIGUOUS_JOINT_FACTOR otherwise)."""
        if self.ambiguous_joint_factor is not None:
            return self.ambiguous_joint_factor
        if getattr(estimator, "gives_canonical_pairs", False):
            return CANONICAL_AMBIGUOUS_JOINT_FACTOR
        return AMBIGUOUS_JOINT_FACTOR


def kalman_factory(estimator, settings: TrackerSettings = TrackerSettings()
                   ) -> Callable[[float], PoseKalmanFilter]:
    """The default filter factory: fps -> a PoseKalmanFilter with the estimator's noise models
    (scaled by settings.r_scale / q_scale / heading_q_scale) and the settings' ambiguity
    handling; an IMMPoseFilter with settings.heading_models where there are two or more."""
    q = np.broadcast_to(np.asarray(estimator.process_noise, float) * settings.q_scale,
                        (N_ANGLES,)).copy()
    q[0] *= settings.heading_q_scale

    kwargs = dict(R=estimator.measurement_covariance * settings.r_scale, q=q,
                  ambiguity_threshold=settings.threshold(estimator),
                  ambiguous_heading_factor=settings.ambiguous_heading_factor,
                  ambiguous_joint_factor=settings.joint_factor(estimator))

    def make(fps: float) -> PoseKalmanFilter:
        if len(settings.heading_models) > 1:
            return IMMPoseFilter(fps, models=settings.heading_models,
                                 switch=settings.heading_switch, **kwargs)
        return PoseKalmanFilter(fps, **kwargs)
    return make


def limb_kalman_factory(estimator, settings: TrackerSettings = TrackerSettings()
                        ) -> Callable[[float], PoseKalmanFilter]:
    """fps -> the PoseKalmanFilter of the output's body angles: kalman_factory's with R
    further scaled by settings.limb_r_scale (LIMB_R_SCALE)."""
    # Its heading is not used (the body angles only), so it needs no heading models.
    return kalman_factory(estimator, replace(settings, heading_models=(),
                                             r_scale=settings.r_scale * settings.limb_r_scale))


def filter_factories(estimator, settings: TrackerSettings = TrackerSettings(),
                     filter_factory: Callable[[float], PoseFilter] | None = None,
                     ) -> tuple[Callable[[float], PoseFilter], Callable[[float], PoseFilter] | None]:
    """(the front/back hypotheses' filter factory, the body angles' filter factory) as the
    tracker runs them: kalman_factory and limb_kalman_factory; with a custom filter_factory,
    that factory and None (its filters give the whole pose, no separate limb filter). A model
    fitted on canonical members (PoseModel.canonical_direction) gets no limb filter either: its
    raw limbs may be the other body's, and the chain's choice of member is the limbs' too."""
    if filter_factory is not None:
        return filter_factory, None
    limbs = (None if getattr(estimator, "canonical_direction", None) is not None
             else limb_kalman_factory(estimator, settings))
    return kalman_factory(estimator, settings), limbs


def front_back_tracker(estimator, fps: float, settings: TrackerSettings = TrackerSettings(),
                       filter_factory: Callable[[float], PoseFilter] | None = None,
                       ) -> FrontBackTracker:
    """A track's front/back hypotheses with the filters of filter_factories."""
    return _front_back_chain(estimator, fps, settings,
                             *filter_factories(estimator, settings, filter_factory))


def _front_back_chain(estimator, fps: float, settings: TrackerSettings, chain, limbs
                      ) -> FrontBackTracker:
    """The one place a track's FrontBackTracker is built: the estimator's switch rates and
    evidence weight, the filter factories chain and limbs (filter_factories)."""
    return FrontBackTracker(chain, fps, **chain_options(estimator),
                            keep_history=settings.keep_history, limb_filter_factory=limbs,
                            offset_memory=settings.travel_offset_memory)


class PoseEstimator(Protocol):
    """What the tracker needs of a trained model."""

    stack_depth: int
    measurement_covariance: np.ndarray      # (54, 54) deg^2, filter R
    process_noise: np.ndarray               # (54,) (deg/s^2)^2, filter q
    ambiguity_threshold: float              # raw heading norm it was trained with

    def describe(self, mask: np.ndarray) -> np.ndarray: ...        # (H, W) bool -> (D,)

    def predict(self, stacked: np.ndarray) -> np.ndarray: ...      # (k*D,) -> (55,)


class PoseFilter(Protocol):
    """What the tracker needs of a per-track filter (PoseKalmanFilter is one)."""

    heading_variance: float                 # deg^2, the heading's measurement variance

    def step(self, raw55: np.ndarray, heading_variance: float | None = None
             ) -> tuple[np.ndarray, bool]: ...    # (55,) -> (filtered (55,), ambiguous)

    def rts_smooth(self, raws: np.ndarray, heading_variance=None) -> np.ndarray: ...


@dataclass
class TrackedPose:
    """One person in one frame: what every sink is given. raw/filtered: (55,) pose vectors
    (degrees; heading as cos, sin); ambiguous: raw heading norm below the threshold; joints_m:
    (18, 3) metres, Y up, for drawing (root placed on an approximate ground position from the
    image); centroid_px: (x, y) pixels; bbox_px: (x, y, w, h) pixels (None when unknown);
    runner_up: (55,) the filtered pose of the next most probable front/back hypothesis and
    runner_up_probability, when that is close (tracker.hypotheses.CLOSE_PROBABILITY), else None;
    novelty: how unlike the training silhouettes the frame's input is (PoseModel.novelty; about
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
        tracker.sinks.geometry.is_unfamiliar."""
        return is_unfamiliar(self.novelty)


@dataclass
class _TrackState:
    """What the tracker keeps per track id: its descriptor history, its front/back hypotheses
    (one filter each) and its direction of travel."""

    stacker: FrameStacker
    hypotheses: FrontBackTracker
    travel: TravelDirection
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
        self.stack_step = stack_step(self.fps, training_fps_of(estimator))
        index = getattr(estimator, "heading_index", None)
        if settings.novelty and index is not None:
            index.typical_distance()     # novelty's scale, computed once: here, not at frame 1
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
        (tracker.mirror_limbs), its mirror image's (D,) (else None), made upright by the
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
                description = (self.describe(person) if descriptions is None
                               else known[id(person)])
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
            travel = TravelDirection(self.fps, self.frame_shape[1], focal_px=self._focal_px)
            step = self.stack_step
            self.tracks[track_id] = _TrackState(
                FrameStacker(self.estimator.stack_depth, step),
                _front_back_chain(self.estimator, self.fps, self.settings, self.filter_factory,
                                  self.limb_filter_factory), travel,
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
        hypotheses = propose_batch(self.estimator, X, mirrored=X_mirror)
        novelty = ([float(v) for v in self.estimator.novelty(X)]
                   if self.settings.novelty and hasattr(self.estimator, "novelty")
                   else [None] * len(X))
        self._lap("regression", clock)
        return hypotheses, novelty

    def _decide(self, track_id: int, person: PersonMask, hypotheses):
        """A track's front/back decision (tracker.hypotheses.Decision) for one frame from its
        hypotheses, the direction of travel as soft evidence."""
        state = self._state(track_id)
        clock = time.perf_counter()
        travel = state.travel.push(person.centroid[0], person.bbox[3])
        decision = state.hypotheses.step(hypotheses, travel)
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
        first pose) smoothed as if the track were those alone (tracker.fixed_lag)."""
        if not self.settings.keep_history:
            raise ValueError("smoothed_track needs TrackerSettings(keep_history=True)")
        return self.tracks[track_id].hypotheses.smoothed(start, stop)

    def smoothed_root_path(self, track_id: int, start: int = 0, stop: int | None = None
                           ) -> np.ndarray:
        """The roots (n, 3) metres of a track's poses start..stop-1 (as smoothed_track's),
        the tracker's own placements smoothed over the video's time (tracker.root_path); needs
        settings.keep_history."""
        if not self.settings.keep_history:
            raise ValueError("smoothed_root_path needs TrackerSettings(keep_history=True)")
        raw, frames = self.roots.get(track_id, start, stop)
        return smoothed_roots(raw, self.fps, frames=frames)
