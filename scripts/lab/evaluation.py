"""Accuracy and jitter of pose estimates over whole sequences: four methods against ground truth.

Methods, all on the same frames:
  per_frame  a k = 1 regressor, frame by frame (the paper's regressor);
  stacked    the stacked (k > 1) regressor's raw output;
  kalman     stacked + the forward Kalman filter (what ``track`` streams);
  smoothed   stacked + Rauch-Tung-Striebel smoothing (``track --smooth``).

Sequences come in two kinds. Joint angles (units "deg"): a CMU BVH motion rendered with our body
from a fixed camera (optionally as a spiral walk), estimates as 55-D pose vectors, compared as 54
angles (heading from (cos, sin), then the 53 joint angles). 3-D points (units "units"): the
paper's released spiral walk, 63-D, regressors trained on its training split here.

Measures (regressor.metrics, DESIGN.md): error (mean angular / point error), jitter (mean
|second difference|) beside the truth's own, acceleration error (jitter of estimate - truth),
heading RMS (angles only), error per body part (angles) or per point (points).
"""
from __future__ import annotations

import struct
import tempfile
import zlib
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import scipy.io
from scipy.io.matlab import MatReadError

from regressor.angles import heading_norm, pose_angles, wrap_deg
from regressor.hypothesis_path import most_probable_path
from regressor.metrics import (acceleration_error, angle_jitter, angular_error,
                               contiguous_folds, mean_point_error, point_jitter, rms_per_angle)
from regressor.optional_parts import predict_batch
from regressor.pose_model import PoseModel
from regressor.rvm import RVMRegressor
from regressor.stacking import stack_frames
from sequences.body import sample_body_shapes
from sequences.measures import DEFAULT_TOP_ANGLES, correlation, pose_measures, skill
from sequences.bvh import read_bvh
from sequences.pose_conversions import PART_OF_ENTRY, motion_to_pose_vectors
from sequences.render import silhouette_mask
from sequences.spiral import line_of_sight_azimuth, spiral_walk
from sequences.video import Actor, load_truth, posed_sequences, scene_camera, write_video
from regressor.errors import SilhouettePoseError
from tracker.cli import VIEW_LAG_S
from tracker.tracks.filtering import ConstantVelocityFilter
from tracker.tracks.filterpy_runs import forward
from tracker.tracks.fixed_lag import replay
from tracker.tracks.proposals import propose_sequence
from tracker.pipeline import PoseTracker, TrackerSettings
from tracker.tracks.proposals import front_back_tracker
from tracker.run import track_video
from tracker.outputs import PoseRecorder
from tracker.video.decode import open_video

METHODS = ("per_frame", "stacked", "kalman", "smoothed")
ANKUR_TRAIN_STARTS = (0, 100, 336, 405, 471, 1530, 1768)   # the 7 training sequences (README)
LARGE_HEADING_ERROR_DEG = 45.0   # a heading error this large is a wrong view, not noise
_CROP_MARGIN_PX = 2


class EvaluationError(SilhouettePoseError, ValueError):
    """An input the evaluation cannot use (file, option, sequence); one-line message."""


@dataclass
class EvaluatedSequence:
    """Estimates of every method on one sequence, aligned frame by frame with the truth.

    units: "deg" (truth and estimates are (T, 55) pose vectors) or "units" ((T, 3P) points);
    estimates: method name -> array shaped like truth; heading_norm: (T,) ||(cos, sin)|| of the
    stacked raw estimate (angles only, else None); ambiguous: (T,) bool, heading_norm below the
    filter's threshold (angles only); ambiguous_per_frame: the same for the per_frame
    estimate's own heading norm; runner_up: (T, 55) the filter's runner-up front/back
    hypothesis where it was close, NaN elsewhere, runner_up_probability (T,) (NaN likewise);
    constant: the constant baseline every method is judged against, the training set's mean
    pose ((55,) or (3P,)); settings: how the sequence and methods were made.
    """

    name: str
    units: str
    truth: np.ndarray
    estimates: dict[str, np.ndarray]
    heading_norm: np.ndarray | None = None
    ambiguous: np.ndarray | None = None
    ambiguous_per_frame: np.ndarray | None = None
    runner_up: np.ndarray | None = None
    runner_up_probability: np.ndarray | None = None
    constant: np.ndarray | None = None
    settings: dict = field(default_factory=dict)


@dataclass(frozen=True)
class CameraOptions:
    """The fixed camera and video: size (height, width) px, azimuth/elevation degrees, distance
    metres, fps, body shape and noise seed, sensor noise (grey levels, videos only)."""

    size: tuple[int, int] = (240, 320)        # (height, width), numpy order, as everywhere
    azimuth_deg: float = 0.0
    elevation_deg: float = 8.0
    distance_m: float = 9.0
    fps: float = 30.0
    seed: int = 0
    noise_sigma: float = 2.0


@dataclass(frozen=True)
class AnkurOptions:
    """Regressor and filter settings for the paper's data, chosen on its training split only.

    Kernel RVM (regressor.rvm, "common" output scale) on sqrt descriptors; stack_depth: k of
    the stacked method. The filter's R is the covariance of held-out residuals over cv_folds
    contiguous training blocks (diagonal), times r_scale (None: chosen on the training split,
    see ankur_noise_models); q is the variance of the training
    poses' second differences (times fps^4, q_scale): nominal fps, the data has no time base.
    """

    width_scale: float = 0.5
    noise: float = 0.03
    min_gain: float = 100.0
    stack_depth: int = 3
    cv_folds: int = 3
    fps: float = 30.0
    r_scale: float | None = None
    q_scale: float = 1.0


R_SCALES = (0.1, 0.25, 0.5, 1.0, 2.0)   # candidate scalings of the paper data's filter R


# ---------------------------------------------------------------- measures

def angle_parts() -> list[str]:
    """Body part of each of the 54 compared angles (heading, torso, head, arms, legs)."""
    return ["heading"] + list(PART_OF_ENTRY[2:])


def measure_angles(est: np.ndarray, truth: np.ndarray) -> dict:
    """Measures of estimated pose vectors est (T, 55) against truth (T, 55); degrees."""
    a, b = pose_angles(est), pose_angles(truth)
    err = np.abs(wrap_deg(a - b))                       # (T, 54)
    parts = np.array(angle_parts())
    return {"error": angular_error(a, b), "jitter": angle_jitter(a),
            "accel_error": acceleration_error(a, b),
            "heading_rms_deg": float(rms_per_angle(a[:, :1], b[:, :1])[0]),
            "per_part": {p: float(err[:, parts == p].mean()) for p in dict.fromkeys(parts)}}


def measure_points(est: np.ndarray, truth: np.ndarray) -> dict:
    """Measures of estimated points est (T, 3P) against truth (T, 3P); data units."""
    dist = np.linalg.norm((est - truth).reshape(len(est), -1, 3), axis=2)   # (T, P)
    return {"error": mean_point_error(est, truth), "jitter": point_jitter(est),
            "accel_error": point_jitter(est - truth),
            "per_part": {f"point {j}": float(d) for j, d in enumerate(dist.mean(0))}}


def constant_pose(model: PoseModel) -> np.ndarray:
    """The model's training-mean pose (55,): heading straight at the camera (its heading is
    never judged: the measures give the constant the true heading), the circular mean of
    every training angle."""
    return np.concatenate([[1.0, 0.0], model.angle_centre_deg])


def honest_measures(seq: EvaluatedSequence, estimate: np.ndarray) -> dict:
    """The measures a flat output cannot fake, for one method's estimate (shaped like
    seq.truth), beside seq.constant: angles: sequences.measures.pose_measures (skill, the
    correlation of the 8 most-moving angles, knee/elbow flexion, MPJPE/PA-MPJPE mm); points:
    the constant's mean point error, skill and the correlation of the 8 most-moving
    coordinates. Empty when the sequence has no constant."""
    if seq.constant is None:
        return {}
    if seq.units == "deg":
        return pose_measures(estimate, seq.truth, seq.constant)
    const_error = mean_point_error(np.broadcast_to(seq.constant, seq.truth.shape), seq.truth)
    error = mean_point_error(estimate, seq.truth)
    top = np.argsort(seq.truth.std(axis=0))[::-1][:DEFAULT_TOP_ANGLES]
    r = correlation(estimate[:, top], seq.truth[:, top])
    return {"constant_error": const_error, "skill": skill(error, const_error),
            "top_coordinates": {"per_coordinate": r.tolist(), "mean": float(r.mean())}}


def evaluate(seq: EvaluatedSequence) -> dict:
    """The evaluation record (JSON-ready): sequence, frames, units, ground_truth_jitter, methods
    {name: error, jitter, accel_error, [heading_rms_deg], per_part}, and for angles the
    ambiguity analysis of :func:`heading_ambiguity`."""
    angles = seq.units == "deg"
    measure = measure_angles if angles else measure_points
    out = {"sequence": seq.name, "frames": int(len(seq.truth)), "units": seq.units,
           "ground_truth_jitter": (angle_jitter(pose_angles(seq.truth)) if angles
                                   else point_jitter(seq.truth)),
           "methods": {m: {**measure(seq.estimates[m], seq.truth),
                           **honest_measures(seq, seq.estimates[m])}
                       for m in METHODS if m in seq.estimates}}
    if angles and seq.ambiguous is not None:
        flags = {"per_frame": seq.ambiguous_per_frame, "stacked": seq.ambiguous,
                 "kalman": seq.ambiguous}
        out["ambiguity"] = {m: heading_ambiguity(seq.estimates[m], seq.truth, flags[m])
                            for m in flags if m in seq.estimates and flags[m] is not None}
        if seq.runner_up is not None:
            out["runner_up"] = runner_up_analysis(seq.estimates["kalman"], seq.runner_up,
                                                  seq.truth, seq.ambiguous)
    out["settings"] = seq.settings
    return out


def heading_errors(est: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Wrapped heading error (T,) deg of pose vectors est (T, 55) against truth (T, 55)."""
    return wrap_deg(pose_angles(est)[:, 0] - pose_angles(truth)[:, 0])


def heading_ambiguity(est: np.ndarray, truth: np.ndarray, ambiguous: np.ndarray,
                      large_deg: float = LARGE_HEADING_ERROR_DEG) -> dict:
    """Do ambiguous frames carry the large heading errors? est, truth (T, 55); ambiguous (T,)
    bool. Returns counts and shares: ambiguous frames, frames with |heading error| > large_deg,
    the share of those that are ambiguous, and heading RMS (deg) in each kind of frame."""
    err = np.abs(heading_errors(est, truth))
    amb = np.asarray(ambiguous, bool)
    large = err > large_deg

    def rms(sel):
        return float(np.sqrt((err[sel] ** 2).mean())) if sel.any() else None

    return {"frames": int(len(err)), "ambiguous_frames": int(amb.sum()),
            "ambiguous_share": float(amb.mean()), "large_deg": large_deg,
            "large_error_frames": int(large.sum()),
            "large_errors_in_ambiguous": int((large & amb).sum()),
            "share_of_large_in_ambiguous": float((large & amb).sum() / large.sum())
            if large.any() else None,
            "heading_rms_ambiguous_deg": rms(amb), "heading_rms_unambiguous_deg": rms(~amb)}


def runner_up_analysis(chosen: np.ndarray, runner_up: np.ndarray, truth: np.ndarray,
                       ambiguous: np.ndarray) -> dict:
    """How often the runner-up hypothesis was the true one. chosen, truth (T, 55); runner_up
    (T, 55), NaN rows where none was reported (not close); ambiguous (T,) bool. "True": nearer
    the truth than the chosen pose (mean absolute error over the 54 angles). Counts on
    ambiguous frames and on all frames; heading RMS if the better of the two had been taken."""
    shown = np.isfinite(runner_up).all(axis=1)
    amb = np.asarray(ambiguous, bool)
    t = pose_angles(truth)
    err_c = np.abs(wrap_deg(pose_angles(chosen) - t)).mean(axis=1)
    alt = np.where(shown[:, None], runner_up, chosen)
    err_r = np.abs(wrap_deg(pose_angles(alt) - t)).mean(axis=1)
    true_alt = shown & (err_r < err_c)
    best = np.where(true_alt[:, None], alt, chosen)
    return {"ambiguous_frames": int(amb.sum()),
            "runner_up_shown_ambiguous": int((shown & amb).sum()),
            "runner_up_true_ambiguous": int((true_alt & amb).sum()),
            "runner_up_shown": int(shown.sum()), "runner_up_true": int(true_alt.sum()),
            "share_true_when_shown_ambiguous": float((true_alt & amb).sum() / (shown & amb).sum())
            if (shown & amb).any() else None,
            "heading_rms_best_of_two_deg": float(np.sqrt((heading_errors(best, truth) ** 2).mean()))}


# ---------------------------------------------------------------- the paper's data

#: The paper's data (its README): training descriptors Y and poses Z, test Y_test and Z_test.
#: ANKUR_TRAIN_STARTS and the scripts' folds assume these rows: any other shape is not it.
ANKUR_SHAPES = {"Y": (1927, 100), "Z": (1927, 63), "Y_test": (418, 100), "Z_test": (418, 63)}


def mixture_path(mixture, X, step_var: float, continuity: float = 1.0, sequence_ids=None,
                 floor: float = 1e-3) -> np.ndarray:
    """The most probable sequence of a fitted regressor.mixture.MixtureRegressor's experts'
    poses, (N, K) of X (N, D) rows in time order, each frame's evidence the gate's log
    p(expert | x) (floored at floor, so an expert no neighbour voted for stays possible), the
    steps between frames scored by a Gaussian of variance step_var
    (regressor.hypothesis_path). Offline: it needs the whole sequence. sequence_ids (N,): the
    chain restarts where the label changes. (N,) for a single output, as predict."""
    mixture._check_fitted("gate_")
    # All experts: their probabilities, renormalised over all of them, are the gate's own.
    poses, prob = mixture.predict_hypotheses(X, len(mixture.experts_))
    log_w = np.log(np.maximum(prob, floor))
    path = most_probable_path(poses, log_w, step_var, continuity, sequence_ids)
    out = poses[np.arange(len(X)), path]
    return out if mixture.n_outputs_ > 1 else out[:, 0]


def load_ankur(path: str | Path) -> dict[str, np.ndarray]:
    """The paper's four arrays (ANKUR_SHAPES, float64) from its .mat file; EvaluationError
    naming the file and the problem for anything else (missing, not a MATLAB file, cut short,
    an array missing, not numbers, of another shape, not finite)."""
    try:
        d = scipy.io.loadmat(str(path))
    # scipy's errors on a file that is not a MATLAB file or is cut short: IndexError on a cut
    # header, zlib and struct errors in compressed or cut data, NotImplementedError for a v7.3
    # (HDF5) file.
    except (OSError, ValueError, TypeError, IndexError, KeyError, EOFError, MemoryError,
            NotImplementedError, MatReadError, zlib.error, struct.error) as exc:
        text = ((isinstance(exc, OSError) and exc.strerror) or " ".join(str(exc).split())
                or type(exc).__name__)
        raise EvaluationError(f"{path}: cannot read it as a MATLAB file ({text})") from None
    missing = [k for k in ANKUR_SHAPES if k not in d]
    if missing:
        raise EvaluationError(f"{path}: not the paper's data (no {', '.join(missing)})")
    data = {}
    for key, shape in ANKUR_SHAPES.items():
        try:
            data[key] = np.asarray(d[key], dtype=np.float64)
        except (ValueError, TypeError):
            raise EvaluationError(f"{path}: not the paper's data ({key} holds no numbers)") \
                from None
        if data[key].shape != shape:
            raise EvaluationError(f"{path}: not the paper's data ({key} is "
                                  f"{'x'.join(map(str, data[key].shape))}, expected "
                                  f"{shape[0]}x{shape[1]})")
        if not np.isfinite(data[key]).all():
            raise EvaluationError(f"{path}: {key} holds a number that is not finite")
    return data


def _ankur_regressor(o: AnkurOptions) -> RVMRegressor:
    return RVMRegressor("gaussian", output_scale="common", width_scale=o.width_scale,
                        noise=o.noise, min_gain=o.min_gain)


def ankur_noise_models(X: np.ndarray, Z: np.ndarray, o: AnkurOptions) -> tuple[np.ndarray, np.ndarray, float]:
    """Filter noise from the training split only: R (63,) held-out residual variances over
    o.cv_folds contiguous blocks of stacked descriptors X (N, kD); q (63,) variance of the
    poses' within-sequence second differences, times fps^4 ((units/s^2)^2). R is scaled by
    o.r_scale, or if that is None by the value of R_SCALES whose filter, run over each training
    sequence's held-out estimates, gives the lowest point error. Returns (R, q, r_scale)."""
    held_out = np.empty_like(Z)
    for hold in contiguous_folds(len(X), o.cv_folds):
        train = np.ones(len(X), bool)
        train[hold] = False
        held_out[hold] = _ankur_regressor(o).fit(X[train], Z[train]).predict(X[hold])
    ids = np.cumsum(np.isin(np.arange(len(Z)), ANKUR_TRAIN_STARTS)) - 1
    d2 = Z[2:] - 2 * Z[1:-1] + Z[:-2]
    same = (ids[2:] == ids[:-2])                     # second differences inside one sequence
    q = d2[same].var(axis=0) * o.fps**4 * o.q_scale
    # Coordinates the data holds fixed (the root point) have no residual: keep R positive.
    R = (held_out - Z).var(axis=0)
    R = np.maximum(R, 1e-6 * R.max())
    if o.r_scale is not None:
        return R * o.r_scale, q, o.r_scale

    def cv_error(scale: float) -> float:
        cv = ConstantVelocityFilter(Z.shape[1], o.fps, R * scale, q, float(np.sqrt(q.mean())))
        filtered = np.vstack([forward(cv, held_out[ids == i]) for i in np.unique(ids)])
        return mean_point_error(filtered, Z)

    best = min(R_SCALES, key=cv_error)
    return R * best, q, best


def ankur_sequence(path: str | Path, options: AnkurOptions = AnkurOptions(),
                   frames: int | None = None) -> EvaluatedSequence:
    """Train on the paper's training split and estimate its test spiral walk with every method.
    frames: evaluate only the first frames of the test sequence (tests)."""
    d = load_ankur(path)
    X, Xt = np.sqrt(d["Y"]), np.sqrt(d["Y_test"][:frames])
    Z, Zt = d["Z"], d["Z_test"][:frames]
    k = options.stack_depth
    Xk = stack_frames(X, k, sequence_starts=list(ANKUR_TRAIN_STARTS))
    per_frame = _ankur_regressor(options).fit(X, Z).predict(Xt)
    stacked_model = _ankur_regressor(options).fit(Xk, Z)
    stacked = stacked_model.predict(stack_frames(Xt, k))
    R, q, r_scale = ankur_noise_models(Xk, Z, options)
    cv = ConstantVelocityFilter(Z.shape[1], options.fps, R, q, rate_std=float(np.sqrt(q.mean())))
    return EvaluatedSequence(
        "ankur spiral walk (test)", "units", Zt,
        {"per_frame": per_frame, "stacked": stacked, "kalman": forward(cv, stacked),
         "smoothed": cv.smooth(stacked)}, constant=Z.mean(axis=0),
        settings={"source": str(path), "regressor": "kernel RVM on sqrt descriptors",
                  **options.__dict__, "chosen_r_scale": r_scale, "relevance_vectors": int(stacked_model.n_basis_)})


# ---------------------------------------------------------------- rendered CMU motion

def cmu_motion(bvh: str | Path, spiral_deg_per_s: float | None, fps: float = 30.0):
    """A BVH motion at fps, optionally turned into a spiral walk (sequences.spiral)."""
    motion = read_bvh(bvh, fps=fps)
    return spiral_walk(motion, spiral_deg_per_s) if spiral_deg_per_s else motion


def render_silhouettes(motion, camera: CameraOptions
                       ) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Silhouettes of the motion from the fixed camera a video of it would use (same body
    shape, ground path, camera fit as sequences.video.write_video), each cropped to the person.

    Returns (masks: list of (h, w) bool crops, truth pose vectors (T, 55) relative to the line
    of sight, image track (T, 2): each silhouette's centroid column and height in pixels)."""
    actor = Actor(motion, shape=sample_body_shapes(1, seed=camera.seed)[0])
    body, posed = posed_sequences([actor], motion.n_frames)
    grounded, hips = posed[0]
    cam = scene_camera(posed, camera.size, camera.azimuth_deg, camera.elevation_deg,
                       camera.distance_m)
    truth = motion_to_pose_vectors(motion, line_of_sight_azimuth(hips, cam.position))
    masks, image_track = [], []
    for t, v in enumerate(grounded):
        mask = silhouette_mask(v, body.faces, body.patch_start, cam)
        ys, xs = np.nonzero(mask.any(axis=1))[0], np.nonzero(mask.any(axis=0))[0]
        if not len(ys):
            raise EvaluationError(f"{motion.source}: frame {t} leaves the camera's view")
        m = _CROP_MARGIN_PX
        masks.append(np.pad(mask[ys[0]:ys[-1] + 1, xs[0]:xs[-1] + 1], m))
        image_track.append((np.nonzero(mask)[1].mean(), ys[-1] - ys[0] + 1))
    return masks, truth, np.array(image_track, dtype=np.float64)


def _model_poses(model: PoseModel, masks: list[np.ndarray]) -> np.ndarray:
    """Raw poses (T, 55) of one sequence of masks by a model, stacking its own descriptors."""
    X = np.array([model.describe(m) for m in masks])
    return predict_batch(model, stack_frames(X, model.stack_depth))


def rendered_sequence(bvh: str | Path, stacked_model: PoseModel, per_frame_model: PoseModel,
                      spiral_deg_per_s: float | None = None, camera: CameraOptions = CameraOptions(),
                      settings: TrackerSettings = TrackerSettings(), frames: int | None = None,
                      ) -> EvaluatedSequence:
    """A CMU motion rendered from a fixed camera, estimated by each method from its silhouettes
    directly (no video, no background subtraction). frames: keep only the first frames."""
    motion = cmu_motion(bvh, spiral_deg_per_s, camera.fps)
    if frames is not None:
        motion = replace(motion, euler_deg=motion.euler_deg[:frames],
                         root_position=motion.root_position[:frames])
    masks, truth, _ = render_silhouettes(motion, camera)
    hypotheses = propose_sequence(stacked_model, masks, mirror=settings.mirror_limbs)
    name = Path(bvh).stem + (f" spiral {spiral_deg_per_s:g} deg/s" if spiral_deg_per_s else "")
    # As the tracker does: front/back hypotheses over time.
    bank = front_back_tracker(stacked_model, camera.fps, replace(settings, keep_history=True))
    decisions = [bank.step(h) for h in hypotheses]
    return _pose_sequence(name, truth, _model_poses(per_frame_model, masks),
                          np.array([h.raw for h in hypotheses]),
                          np.array([d.filtered for d in decisions]), bank.smoothed(),
                          np.array([d.ambiguous for d in decisions]),
                          *_runner_ups([(d.runner_up, d.runner_up_probability) for d in decisions]),
                          settings.threshold(stacked_model), _resolved(settings, stacked_model),
                          {"path": "rendered silhouettes", "camera": camera.__dict__},
                          constant=constant_pose(stacked_model))


def _resolved(settings: TrackerSettings, model) -> TrackerSettings:
    """settings with the model-dependent defaults filled in, as the report records them."""
    return replace(settings, ambiguous_joint_factor=settings.joint_factor(model))


def _runner_ups(pairs) -> tuple[np.ndarray, np.ndarray]:
    """(runner-up poses (T, 55), probabilities (T,)), NaN where none, from (pose, p) pairs."""
    poses = np.array([np.full(55, np.nan) if pose is None else pose for pose, _ in pairs])
    return poses, np.array([np.nan if p is None else p for _, p in pairs])


def _pose_sequence(name, truth, per_frame, raw, filtered, smoothed, ambiguous, runner_up,
                   runner_up_probability, threshold: float,
                   tracker_settings: TrackerSettings, settings: dict,
                   constant: np.ndarray | None = None) -> EvaluatedSequence:
    """threshold: the ambiguity threshold in use; filtered, smoothed (T, 55): the tracker's
    online and --smooth outputs; ambiguous (T,) bool; constant: the constant baseline (55,)."""
    return EvaluatedSequence(
        name, "deg", truth,
        {"per_frame": per_frame, "stacked": raw, "kalman": filtered, "smoothed": smoothed},
        heading_norm=heading_norm(raw), ambiguous=np.asarray(ambiguous, bool),
        ambiguous_per_frame=heading_norm(per_frame) < threshold,
        runner_up=runner_up, runner_up_probability=runner_up_probability, constant=constant,
        settings={**settings, "filter": {**asdict(tracker_settings),
                                         "ambiguity_threshold": threshold}})


def run_longest_track(video: Path, model: PoseModel, settings: TrackerSettings,
                      workers: int = 1) -> tuple[PoseTracker, PoseRecorder, int]:
    """Run the ``track`` loop on a one-person video (one person at most, history kept); returns
    the tracker, what it recorded and the id of its longest track. A run cut short by Ctrl-C
    is not measured; nobody tracked is an EvaluationError."""
    recorder = PoseRecorder()
    source = open_video(video)
    tracker = PoseTracker(model, source.fps, replace(settings, max_people=1, keep_history=True))
    track_video(source, tracker, [recorder], workers=workers).stop_if_interrupted()
    by_track = recorder.by_track()
    if not by_track:
        raise EvaluationError(f"{video}: nobody was tracked")
    return tracker, recorder, max(by_track, key=lambda t: len(by_track[t]))


def track_longest(video: Path, model: PoseModel, settings: TrackerSettings,
                  lag_s: float = VIEW_LAG_S):
    """Run the ``track`` loop (tracker.run.track_video) on a one-person video: (frame indices
    (n,), raw (n, 55), filtered (n, 55), smoothed (n, 55), ambiguous (n,), runner-up poses
    (n, 55) and probabilities (n,), NaN where none, novelty (n,), NaN unless
    settings.novelty, and the poses ``track --lag lag_s`` gives (n, 55): tracker.tracks.fixed_lag)
    of its longest track."""
    # The same poses on two cores.
    tracker, recorder, track_id = run_longest_track(video, model, settings, workers=2)
    poses = recorder.by_track()[track_id]
    lagged = [p.filtered for p in replay(tracker, recorder.frames(), lag_s)
              if p.track_id == track_id]
    return (np.array([p.frame_index for p in poses]), np.array([p.raw for p in poses]),
            np.array([p.filtered for p in poses]), tracker.smoothed_track(track_id),
            np.array([p.ambiguous for p in poses]),
            *_runner_ups([(p.runner_up, p.runner_up_probability) for p in poses]),
            np.array([np.nan if p.novelty is None else p.novelty for p in poses]),
            np.array(lagged))


def write_camera_video(path: str | Path, motion, camera: CameraOptions = CameraOptions(),
                       frames: int | None = None) -> None:
    """Write the motion as an mp4 (and its truth file) seen by the fixed camera (body shape
    and noise from camera.seed); frames: only the first frames."""
    write_video(path, [Actor(motion, shape=sample_body_shapes(1, seed=camera.seed)[0])],
                size=camera.size, fps=camera.fps, azimuth_deg=camera.azimuth_deg,
                elevation_deg=camera.elevation_deg, distance_m=camera.distance_m,
                noise_sigma=camera.noise_sigma, seed=camera.seed, n_frames=frames)


def video_sequence(bvh: str | Path, stacked_model: PoseModel, per_frame_model: PoseModel,
                   spiral_deg_per_s: float | None = None, camera: CameraOptions = CameraOptions(),
                   settings: TrackerSettings = TrackerSettings(), frames: int | None = None,
                   video: Path | None = None) -> EvaluatedSequence:
    """The motion written as an mp4 (sequences.video) and run through the real ``track`` loop
    (background subtraction, association, stacking, filter) with these settings (at most one
    person); kalman is the pipeline's own filtered output. Evaluated on the frames of the
    longest track that both models tracked. video: where to write (default temporary)."""
    motion = cmu_motion(bvh, spiral_deg_per_s, camera.fps)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(video) if video is not None else Path(tmp) / "evaluation.mp4"
        write_camera_video(path, motion, camera, frames)
        truth = load_truth(path)["pose"][:, 0]
        idx, raw, filtered, smoothed, ambiguous, alt, alt_p = track_longest(path, stacked_model,
                                                                             settings)[:7]
        idx1, raw1 = track_longest(path, per_frame_model, settings)[:2]
    common, a, b = np.intersect1d(idx, idx1, return_indices=True)
    if len(common) < 3:
        raise EvaluationError(f"{bvh}: fewer than 3 frames were tracked")
    name = Path(bvh).stem + (f" spiral {spiral_deg_per_s:g} deg/s" if spiral_deg_per_s else "")
    seq = _pose_sequence(name, truth[common], raw1[b], raw[a], filtered[a], smoothed[a],
                         ambiguous[a], alt[a], alt_p[a], settings.threshold(stacked_model),
                         _resolved(settings, stacked_model),
                         {"path": "video through track", "camera": camera.__dict__,
                          "frames_in_video": int(len(truth)), "frames_tracked": int(len(common))},
                         constant=constant_pose(stacked_model))
    return seq
