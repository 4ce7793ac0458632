"""Ablation of the tracker's mechanisms: each one removed against all present (issue 51).

    python scripts/ablation.py [--videos DIR] [--json OUT] [--only NAME ...] [--skip-real]
        [--skip-renders] [--reversed] [--bvh-dir DIR] [--trials DIR ...]

The results: docs/ablation.md.

Each video is tracked once as ``track`` tracks it (tracker.run.track_video, one process): its
silhouettes and descriptors (with the mirror images') are kept, and every variant replays only
the stages after them (PoseTracker.track_frames with the kept people and descriptions: the
association, the regression, the front/back chain, the filters and the smoother), so a
variant costs a few seconds per video. The default variant's replay equals the ``track`` run
(tests/test_ablation.py).

Each variant removes one mechanism and puts in its simplest natural replacement (VARIANTS; the
toggles change nothing unless asked: TrackerSettings fields, a model copy, or a module function
patched for the replay only):

  ambiguity       no R inflation on ambiguous frames (heading and joints factor 1)
  flips           no front/back flip hypotheses: one hypothesis per frame, the member or its
                  flip by that frame's own evidence (the side classifier), no chain
  side_classifier no side classifier evidence (its table flat at its overall rate)
  switch          no learned switch probabilities (every transition 0.5)
  mirror          no mirror-image averaging of the limbs
  member_path     smoothed limbs' member picked per frame by the smoothed heading (no Viterbi)
  limb_networks   no limb networks: the mixture's own pose and its flip as the hypotheses (the
                  chain before canonical pairs: raw-nearer table, pose/flip switch rates), the
                  limb filter on the mixture's pose; the side classifier goes with them
  stacking        the per-frame model regressor/models/per_frame_model.npz (k = 1) through the
                  same tracker; not a clean ablation: that file is a single RVM on the
                  shape-context histogram alone (no layout, mixture, limb networks, side
                  classifier), described anew from the kept silhouettes

Measures. Validation renders (the model's validation trials 02_02, 08_03, 05_02, 09_04, 02_05
as 30 deg/s spiral walks and from a fixed camera, 06_10 and 07_12 from a fixed camera; 12
videos rendered once into --videos; --reversed: also the same motions time-reversed, i.e.
walking backwards, in a table of their own): err53, corr8, heading RMS of the longest track,
filtered and smoothed (sequences.measures.pose_measures), mean over videos; the noise: the standard
error over videos of the paired difference. Real video (Pose2Sim's balancing and swings
trials, the four views each, as scripts/evaluate_real.py measures the subject): mean over
views of the correlation with the reference over the 8 limb angles (both trials) and, for
balancing, over the four knee/elbow flexions and their error; cross-view heading RMS (all
filtered and smoothed); the noise: standard error over views for the per-view figures, a
paired block bootstrap over frames (15-frame blocks, 2,000 draws, 95 % interval) for the
cross-view heading.
"""
from __future__ import annotations

import contextlib
import functools
import json
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

import tracker.tracks.hypotheses as hyp
from regressor.pose_model import load_pose_model
from sequences.measures import pose_measures
from sequences.pose2sim import TRIALS
from lab.pose2sim_trial import missing_trial
from tracker.one_line_parser import OneLineParser
from lab.evaluation import CameraOptions, cmu_motion, constant_pose, \
    write_camera_video
from tracker.pipeline import PoseTracker, TrackerSettings
from tracker.run import track_video
from tracker.outputs import PoseRecorder
from tracker.video.decode import open_video

REPO = Path(__file__).resolve().parents[1]
SPIRAL_TRIALS = ("02_02", "08_03", "05_02", "09_04", "02_05")
FIXED_TRIALS = SPIRAL_TRIALS + ("06_10", "07_12")
BLOCK_FRAMES = 15
COUNT_CORR = 0.005            # a video counts as worse / better beyond these differences
COUNT_HEAD_DEG = 1.0
BOOTSTRAP_DRAWS = 2000


# ---------------------------------------------------------------- variants

@dataclass(frozen=True)
class Variant:
    """One mechanism removed: name, what replaces it (one line), settings overrides
    (TrackerSettings fields), whether the mirror images' descriptors are kept, whether the
    people are described anew by the variant's model (its descriptor differs); parts: the
    names of several variants removed together."""

    name: str
    what: str
    settings: dict = field(default_factory=dict)
    mirror: bool = True
    describe: bool = False       # describe the people anew (another model's descriptor)
    parts: tuple = ()            # several variants' removals at once


VARIANTS = (
    Variant("present", "every mechanism as shipped"),
    Variant("ambiguity", "no R inflation on ambiguous frames (factors 1)",
            {"ambiguous_heading_factor": 1.0, "ambiguous_joint_factor": 1.0}),
    Variant("flips", "one hypothesis a frame (member or flip by its own evidence), no chain"),
    Variant("side_classifier", "no side-classifier evidence (table flat)"),
    Variant("switch", "switch probabilities 0.5 (no learned switching)"),
    Variant("mirror", "no mirror-image averaging of the limbs", {"mirror_limbs": False},
            mirror=False),
    Variant("member_path", "smoothed limbs' member by the smoothed heading, no Viterbi"),
    Variant("limb_networks", "mixture's pose and flip as hypotheses, no limb networks "
            "(and so no side classifier)"),
    Variant("stacking", "the per-frame model (k = 1; a single RVM: no layout, mixture, limb "
            "networks or side classifier either)", mirror=False, describe=True),
)
BY_NAME = {v.name: v for v in VARIANTS}
PER_FRAME_MODEL = REPO / "regressor" / "models" / "per_frame_model.npz"


def _flat(priors, **tables):
    """priors (CanonicalPriors) with the named tables flat at their overall rate."""
    out = {}
    for table, overall in tables.items():
        out[table] = tuple(getattr(priors, overall) for _ in getattr(priors, table))
    return replace(priors, **out)


def _one_hypothesis(original):
    """canonical_hypotheses reduced to the one hypothesis its own evidence favours."""
    def reduced(*args, **kwargs):
        h = original(*args, **kwargs)
        j = int(np.argmax(h.log_evidence))
        return replace(h, poses=h.poses[j:j + 1], log_evidence=np.zeros(1))
    return reduced


def _transition_matrix(original):
    """transition_matrix that also takes one state (K = 1)."""
    def matrix(K, switch=hyp.SWITCH_PROBABILITY):
        return np.ones((1, 1)) if K == 1 else original(K, switch)
    return matrix


@contextlib.contextmanager
def applied(variant: Variant, model):
    """Within the block: (the model, TrackerSettings) the variant tracks with. Module patches
    are undone on leaving; the model given is never changed (a copy where it must differ).
    A variant with parts removes each of theirs."""
    names = variant.parts or (variant.name,)
    settings = TrackerSettings(max_people=None)
    for name in names:
        settings = replace(settings, **BY_NAME[name].settings)
    with contextlib.ExitStack() as stack:
        patch = stack.enter_context(_Patches())
        for name in names:
            model = _removed(name, model, patch)
        yield model, settings


def _removed(name: str, model, patch):
    """The model the variant ``name`` tracks with (a copy where it differs), its module
    patches made through patch(owner, attribute, value)."""
    priors = hyp.canonical_priors(model)
    if name == "flips":
        patch(hyp, "canonical_hypotheses", _one_hypothesis(hyp.canonical_hypotheses))
        patch(hyp, "transition_matrix", _transition_matrix(hyp.transition_matrix))
    elif name == "side_classifier":
        model = replace(model, canonical_priors=_flat(priors, by_front="overall"))
    elif name == "switch":
        model = replace(model, canonical_priors=replace(priors, switch=(0.5, 0.5)))
    elif name == "member_path":
        patch(hyp, "members_over_time",
              lambda limbs, headings, ratio=1.0: hyp.pick_member(limbs, headings))
    elif name == "limb_networks":
        model = replace(model, limb_net=None, side_classifier=None, canonical_priors=None)
    elif name == "stacking":
        model = _per_frame_model()
    elif name not in BY_NAME:
        raise ValueError(f"unknown variant {name!r}")
    return model


@functools.lru_cache(maxsize=1)
def _per_frame_model():
    return load_pose_model(PER_FRAME_MODEL)


class _Patches:
    """setattr that is undone on leaving (a context manager giving the setter)."""

    def __enter__(self):
        self.saved = []
        return self.set

    def set(self, owner, attribute, value):
        self.saved.append((owner, attribute, owner.__dict__[attribute]))
        setattr(owner, attribute, value)

    def __exit__(self, *exc):
        for owner, attribute, value in reversed(self.saved):
            setattr(owner, attribute, value)
        return False


# ---------------------------------------------------------------- capture and replay

class _Capturing(PoseTracker):
    """PoseTracker that keeps every chunk track_frames is given (people, descriptions)."""

    def track_frames(self, frames):
        self.chunks.append([tuple(f) for f in frames])
        return super().track_frames(frames)


@dataclass
class Capture:
    """One video's people and descriptions as ``track`` made them: chunks as track_frames
    took them; fps; frame_shape (H, W); poses: the ``track`` run's own (TrackedPose list);
    smoothed: its smoothed tracks {track id: (n, 55)}; seconds: the run's CPU time."""

    chunks: list
    fps: float
    frame_shape: tuple
    poses: list
    smoothed: dict
    seconds: float


def capture(video: Path, model, settings: TrackerSettings = TrackerSettings()) -> Capture:
    """Track a video as ``track`` does (one process) and keep its people and descriptions."""
    clock = time.process_time()
    source = open_video(video)
    tracker = _Capturing(model, source.fps, settings)
    tracker.chunks = []
    recorder = PoseRecorder()
    track_video(source, tracker, [recorder], workers=1).stop_if_interrupted()
    smoothed = {t: tracker.smoothed_track(t) for t in tracker.tracks}
    return Capture(tracker.chunks, source.fps, tracker.frame_shape, recorder.poses, smoothed,
                   time.process_time() - clock)


def replay(cap: Capture, model, settings: TrackerSettings, mirror: bool = True,
           describe: bool = False) -> tuple[list, dict]:
    """The poses (TrackedPose list, in track_video's order) and smoothed tracks {id: (n,
    55)} of the captured video tracked with model and settings from its kept people and
    descriptions; mirror False drops the mirror images' descriptors; describe: the people
    are described anew by the model (as track_frames does without descriptions)."""
    tracker = PoseTracker(model, cap.fps, settings)
    tracker._set_frame_shape(cap.frame_shape)
    mirror = mirror and tracker._mirror
    poses = []
    for chunk in cap.chunks:
        frames = [(i, t, people, None if describe else _descriptions(d, mirror))
                  for i, t, people, d in chunk]
        for frame_poses, _ in tracker.track_frames(frames):
            poses.extend(frame_poses)
    return poses, {t: tracker.smoothed_track(t) for t in tracker.tracks}


def _descriptions(descriptions, mirror: bool):
    if descriptions is None or mirror:
        return descriptions
    return [None if d is None else (d[0], None) for d in descriptions]


def longest_track(poses: list, smoothed: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frame indices (n,), filtered (n, 55), smoothed (n, 55)) of the longest track."""
    counts = {}
    for p in poses:
        counts[p.track_id] = counts.get(p.track_id, 0) + 1
    best = max(counts, key=counts.get)
    rows = [p for p in poses if p.track_id == best]
    return (np.array([p.frame_index for p in rows]), np.array([p.filtered for p in rows]),
            smoothed[best])


# ---------------------------------------------------------------- renders

def render_videos(bvh_dir: Path, out: Path, reverse: bool = False) -> list[tuple[str, Path]]:
    """The 12 validation videos (rendered once into out): (name, path); reverse: the same
    motions time-reversed (backward walks; reversed before the spiral, as
    lab.hypothesis_priors.validation_renders)."""
    out.mkdir(parents=True, exist_ok=True)
    videos = []
    tag = " reversed" if reverse else ""
    for kind, trials, spiral in (("spiral", SPIRAL_TRIALS, 30.0), ("fixed", FIXED_TRIALS, None)):
        for trial in trials:
            path = out / f"{trial}_{kind}{'_reversed' if reverse else ''}.mp4"
            if not path.is_file():
                write_camera_video(path, _motion(bvh_dir / f"{trial}.bvh", spiral, reverse),
                                   CameraOptions())
            videos.append((f"{trial} {kind}{tag}", path))
    return videos


def _motion(bvh: Path, spiral: float | None, reverse: bool):
    """The trial's motion at 30 fps, time-reversed if asked, then as a spiral walk if asked."""
    if not reverse:
        return cmu_motion(bvh, spiral)
    from sequences.bvh import read_bvh
    from sequences.spiral import spiral_walk
    motion = read_bvh(bvh, fps=30.0)
    motion = replace(motion, euler_deg=motion.euler_deg[::-1].copy(),
                     root_position=motion.root_position[::-1].copy())
    return spiral_walk(motion, spiral) if spiral else motion


def render_measures(frames, filtered, smoothed, truth, constant) -> dict:
    """err53, corr8, heading RMS of filtered and smoothed poses at frames against truth."""
    out = {}
    for kind, est in (("filtered", filtered), ("smoothed", smoothed)):
        m = pose_measures(est, truth[frames], constant)
        out[kind] = {"err53": m["error_deg"], "corr8": m["top_angles"]["mean"],
                     "head": m["heading_rms_deg"]}
    return out


def run_renders(videos, model, variants, log) -> dict:
    """{variant: {video: render_measures}} and CPU seconds per variant."""
    from sequences.video import load_truth
    constant = constant_pose(model)
    results = {v.name: {} for v in variants}
    seconds = {v.name: 0.0 for v in variants}
    seconds["capture"] = 0.0
    for name, path in videos:
        truth = load_truth(path)["pose"][:, 0]
        cap = capture(path, model)
        seconds["capture"] += cap.seconds
        for v in variants:
            clock = time.process_time()
            with applied(v, model) as (m, settings):
                poses, smoothed = replay(cap, m, settings, v.mirror, v.describe)
            frames, filtered, smooth = longest_track(poses, smoothed)
            results[v.name][name] = render_measures(frames, filtered, smooth, truth, constant)
            seconds[v.name] += time.process_time() - clock
            log(f"{name} {v.name}: " + json.dumps(results[v.name][name]))
    return {"measures": results, "cpu_s": seconds}


# ---------------------------------------------------------------- real video

def run_real(trial_dirs: list[Path], model, variants, log) -> dict:
    """{trial name: {"measures": {variant: _real_summary}, "cpu_s"}} on Pose2Sim's trials
    (balancing, swings), the subject's rows chosen as scripts/evaluate_real.py chooses them."""
    return {Path(d).name: _run_trial(Path(d), model, variants, log) for d in trial_dirs}


def _run_trial(trial_dir: Path, model, variants, log) -> dict:
    """One Pose2Sim trial: every variant's _real_summary and CPU seconds."""
    from sequences.pose2sim import VIEWS
    from lab.pose2sim_trial import checked_trial
    real = _load_script("evaluate_real")
    trial = checked_trial(trial_dir)
    constant = constant_pose(model)
    caps = {}
    seconds = {v.name: 0.0 for v in variants}
    seconds["capture"] = 0.0
    for view in VIEWS:
        caps[view] = capture(trial.video(view), model)
        seconds["capture"] += caps[view].seconds
    results = {}
    for v in variants:
        clock = time.process_time()
        subject = {}
        per_view = {}
        with applied(v, model) as (m, settings):
            for view in VIEWS:
                poses, smoothed = replay(caps[view], m, settings, v.mirror, v.describe)
                track = _view_track(real, poses, smoothed)
                per_view[view], rows = real.evaluate_view(trial, view, track, constant)
                subject[view] = (track.frames[rows], track.filtered[rows], track.smoothed[rows])
        results[v.name] = _real_summary(trial, per_view, subject)
        seconds[v.name] += time.process_time() - clock
        log(f"{trial_dir.name} {v.name}: " + json.dumps(
            {kind: {k: val for k, val in m.items() if not k.startswith("_")}
             for kind, m in results[v.name].items()}))
    return {"measures": results, "cpu_s": seconds}


def _view_track(real, poses, smoothed):
    """evaluate_real's ViewTrack of replayed poses (lagged: the filtered, not measured)."""
    order = {t: iter(s) for t, s in smoothed.items()}
    filtered = np.array([p.filtered for p in poses])
    return real.ViewTrack(np.array([p.frame_index for p in poses]), filtered,
                          np.array([p.raw for p in poses]),
                          np.array([next(order[p.track_id]) for p in poses]),
                          np.array([p.track_id for p in poses]),
                          np.array([p.bbox_px for p in poses], dtype=float),
                          np.full(len(poses), np.nan), filtered)


def _real_summary(trial, per_view: dict, subject: dict) -> dict:
    """Means over views of the flexion correlation (4 angles) and error, per kind, with the
    per-view values; the cross-view heading errors (pairs, T) per kind on the common frames."""
    from itertools import combinations

    from sequences.pose2sim import camera_azimuth_deg
    from sequences.pose_vector import heading_deg
    from regressor.angles import wrap_deg
    views = sorted(per_view)
    out = {}
    for kind in ("filtered", "smoothed"):
        corr = [float(np.nanmean(per_view[v][kind]["flexion"]["corr_per_angle"])) for v in views]
        err = [float(per_view[v][kind]["flexion"]["error"]) for v in views]
        limbs = [float(np.nanmean(per_view[v][kind]["limbs"]["corr_per_angle"]))
                 for v in views]
        out[kind] = {"flex_corr": corr, "flex_err": err, "limb8_corr": limbs,
                     "flex_corr_per_angle": np.mean([per_view[v][kind]["flexion"]
                                                     ["corr_per_angle"] for v in views],
                                                    axis=0).tolist()}
    common = subject[views[0]][0]
    for v in views[1:]:
        common = np.intersect1d(common, subject[v][0])
    az = {v: camera_azimuth_deg(trial, v, common) for v in views}
    for col, kind in ((1, "filtered"), (2, "smoothed")):
        head = {}
        for v in views:
            frames, poses = subject[v][0], subject[v][col]
            # one row per common frame (the first of the subject's rows at that frame)
            _, first = np.unique(frames, return_index=True)
            keep = first[np.isin(frames[first], common)]
            head[v] = heading_deg(poses[keep])
        h_err = np.array([wrap_deg((head[i] - head[j]) - (az[j] - az[i]))
                          for i, j in combinations(views, 2)])
        out[kind]["cross_heading"] = float(np.sqrt((h_err ** 2).mean()))
        out[kind]["_cross_errors"] = h_err
    return out


def _load_script(name: str):
    import importlib.util
    spec = importlib.util.spec_from_file_location(name, REPO / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# ---------------------------------------------------------------- noise and table

def paired(base: list, other: list) -> tuple[float, float, float, float]:
    """(mean of base, mean of other, mean difference other - base, its standard error over
    the paired items)."""
    a, b = np.asarray(base, float), np.asarray(other, float)
    d = b - a
    se = float(d.std(ddof=1) / np.sqrt(len(d))) if len(d) > 1 else float("nan")
    return float(a.mean()), float(b.mean()), float(d.mean()), se


def block_bootstrap_rms(base: np.ndarray, other: np.ndarray, block: int = BLOCK_FRAMES,
                        draws: int = BOOTSTRAP_DRAWS, seed: int = 0) -> tuple[float, float]:
    """95 % interval of RMS(other) - RMS(base) over frames resampled in blocks; base and
    other (pairs, T) errors at the same frames."""
    T = base.shape[1]
    n_blocks = max(1, -(-T // block))
    rng = np.random.default_rng(seed)
    starts = rng.integers(0, max(1, T - block + 1), size=(draws, n_blocks))
    idx = (starts[:, :, None] + np.arange(block)).reshape(draws, -1)[:, :T]
    idx = np.minimum(idx, T - 1)
    rms = lambda e: np.sqrt((e[:, idx] ** 2).mean(axis=(0, 2)))     # noqa: E731
    d = rms(other) - rms(base)
    return float(np.percentile(d, 2.5)), float(np.percentile(d, 97.5))


def main(argv=None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--videos", type=Path, default=Path("/work/cache/ablation/videos"))
    ap.add_argument("--bvh-dir", type=Path,
                    default=TRIALS["balancing"].parents[1] / "cmu" / "bvh")
    ap.add_argument("--trials", type=Path, nargs="+", default=list(TRIALS.values()),
                    help="Pose2Sim trial folders (default balancing and swings)")
    ap.add_argument("--json", type=Path, default=Path("/work/cache/ablation/ablation.json"))
    ap.add_argument("--only", nargs="+", choices=[v.name for v in VARIANTS[1:]])
    ap.add_argument("--skip-real", action="store_true")
    ap.add_argument("--skip-renders", action="store_true")
    ap.add_argument("--from-json", type=Path, metavar="JSON",
                    help="print the tables of an earlier run's --json, run nothing")
    ap.add_argument("--reversed", action="store_true",
                    help="also the 12 renders time-reversed (backward walks), a table of their own")
    args = ap.parse_args(argv)
    if args.from_json is not None:
        if not args.from_json.is_file():
            ap.error(f"--from-json {args.from_json}: no such file")
        print(format_table(json.loads(args.from_json.read_text())))
        return 0
    for trial in [] if args.skip_real else args.trials:
        if missing_trial(trial):
            ap.error(missing_trial(trial))
    if not args.skip_renders and not args.bvh_dir.is_dir():
        ap.error(f"--bvh-dir {args.bvh_dir}: no such folder (the CMU BVH files)")
    if args.videos.exists() and not args.videos.is_dir():
        ap.error(f"--videos {args.videos} is a file, not a folder")
    variants = [VARIANTS[0]] + [v for v in VARIANTS[1:] if not args.only or v.name in args.only]
    model = load_pose_model()
    log = lambda text: print(text, file=sys.stderr, flush=True)     # noqa: E731
    out = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
           "variants": {v.name: v.what for v in variants}}
    with threadpool_limits(1):
        if not args.skip_renders:
            videos = render_videos(args.bvh_dir, args.videos)
            if args.reversed:
                videos += render_videos(args.bvh_dir, args.videos, reverse=True)
            out["renders"] = run_renders(videos, model, variants, log)
        if not args.skip_real:
            out["real"] = run_real(args.trials, model, variants, log)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(out, indent=1, default=_jsonable))
    print(format_table(out))
    return 0


def _jsonable(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(type(x).__name__)


def _render_table(title: str, r: dict, names: list, videos: list) -> list[str]:
    """The renders' two tables (differences with their noise; videos worse / better)."""
    lines = [f"{title} ({len(videos)} videos; mean over videos, present -> removed, "
             "difference +- its standard error over videos):", "",
             "| removed | err53 filt | corr8 filt | head filt | err53 smooth | "
             "corr8 smooth | head smooth |", "|---|---|---|---|---|---|---|"]
    for n in names:
        cells = []
        for kind in ("filtered", "smoothed"):
            for key, fmt in (("err53", ".2f"), ("corr8", ".3f"), ("head", ".1f")):
                a, b, d, se = paired([r["present"][v][kind][key] for v in videos],
                                     [r[n][v][kind][key] for v in videos])
                cells.append(f"{a:{fmt}} -> {b:{fmt}} ({d:+{fmt}} +- {se:{fmt}})")
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    lines += ["", f"{title}: videos where removing it is worse / better (corr8 by more than "
              f"{COUNT_CORR}, heading RMS by more than {COUNT_HEAD_DEG:g} deg):", "",
              "| removed | corr8 filt | head filt | corr8 smooth | head smooth |",
              "|---|---|---|---|---|"]
    for n in names:
        cells = []
        for kind in ("filtered", "smoothed"):
            for key, margin, sign in (("corr8", COUNT_CORR, 1), ("head", COUNT_HEAD_DEG, -1)):
                d = sign * np.array([r[n][v][kind][key] - r["present"][v][kind][key]
                                     for v in videos])
                cells.append(f"{int((d < -margin).sum())} / {int((d > margin).sum())}")
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    return lines + [""]


#: The real trials' columns: (key, label, format); flexion only for balancing (swings' brief
#: is the 8 limb angles), cross-view heading for both.
REAL_COLUMNS = {"balancing": (("flex_corr", "flex corr", ".3f"), ("flex_err", "flex err", ".1f"),
                              ("limb8_corr", "8-angle corr", ".3f"), ("cross", "cross head", "")),
                "swings": (("limb8_corr", "8-angle corr", ".3f"), ("cross", "cross head", ""))}


def _real_table(trial: str, r: dict, names: list) -> list[str]:
    """One Pose2Sim trial's table: present -> removed (difference +- standard error over the
    4 views; cross-view heading: the 95 % block-bootstrap interval of the difference)."""
    columns = REAL_COLUMNS.get(trial, REAL_COLUMNS["swings"])
    head = [f"{label} {kind[:6]}" for kind in ("filtered", "smoothed") for _, label, _ in columns]
    lines = [f"Pose2Sim {trial} (4 views; present -> removed (difference +- standard error over "
             "views; cross-view heading RMS: 95 % block-bootstrap interval of the difference)):",
             "", "| removed | " + " | ".join(head) + " |", "|---" * (len(head) + 1) + "|"]
    for n in names:
        cells = []
        for kind in ("filtered", "smoothed"):
            for key, _, fmt in columns:
                if key != "cross":
                    a, b, d, se = paired(r["present"][kind][key], r[n][kind][key])
                    cells.append(f"{a:{fmt}} -> {b:{fmt}} ({d:+{fmt}} +- {se:{fmt}})")
                    continue
                base = np.asarray(r["present"][kind]["_cross_errors"])
                other = np.asarray(r[n][kind]["_cross_errors"])
                a, b = r["present"][kind]["cross_heading"], r[n][kind]["cross_heading"]
                if base.shape == other.shape:
                    lo, hi = block_bootstrap_rms(base, other)
                    cells.append(f"{a:.1f} -> {b:.1f} [{lo:+.1f}, {hi:+.1f}]")
                else:
                    cells.append(f"{a:.1f} -> {b:.1f} (other frames)")
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    return lines + [""]


def summary_table(out: dict) -> list[str]:
    """One row per variant: the difference removed - present of the headline measures with
    its noise (renders: +- standard error over all renders; real: over the 4 views, and the
    95 % block-bootstrap interval for the cross-view heading)."""
    names = [n for n in out["variants"] if n != "present"]
    cols, rows = [], {n: [] for n in names}
    if "renders" in out:
        r = out["renders"]["measures"]
        videos = list(r["present"])
        for kind, key, fmt in (("filtered", "err53", ".2f"), ("filtered", "corr8", ".3f"),
                               ("filtered", "head", ".1f"), ("smoothed", "corr8", ".3f"),
                               ("smoothed", "head", ".1f")):
            cols.append(f"renders {key} {kind[:6]}")
            for n in names:
                _, _, d, se = paired([r["present"][v][kind][key] for v in videos],
                                     [r[n][v][kind][key] for v in videos])
                rows[n].append(f"{d:+{fmt}} +- {se:{fmt}}")
    for trial, result in out.get("real", {}).items():
        r = result["measures"]
        keys = ((("flex_corr", ".3f"), ("flex_err", ".1f")) if trial == "balancing"
                else (("limb8_corr", ".3f"),))
        for key, fmt in keys:
            cols.append(f"{trial} {key} filt")
            for n in names:
                _, _, d, se = paired(r["present"]["filtered"][key], r[n]["filtered"][key])
                rows[n].append(f"{d:+{fmt}} +- {se:{fmt}}")
        cols.append(f"{trial} cross head filt")
        for n in names:
            base = np.asarray(r["present"]["filtered"]["_cross_errors"])
            other = np.asarray(r[n]["filtered"]["_cross_errors"])
            d = r[n]["filtered"]["cross_heading"] - r["present"]["filtered"]["cross_heading"]
            lo, hi = block_bootstrap_rms(base, other) if base.shape == other.shape \
                else (np.nan, np.nan)
            rows[n].append(f"{d:+.1f} [{lo:+.1f}, {hi:+.1f}]")
    return (["Removed - present (renders: all of them, +- standard error over videos; real: "
             "+- standard error over views, cross-view heading RMS with its 95 % "
             "block-bootstrap interval):", "", "| removed | " + " | ".join(cols) + " |",
             "|---" * (len(cols) + 1) + "|"]
            + [f"| {n} | " + " | ".join(rows[n]) + " |" for n in names] + [""])


def format_table(out: dict) -> str:
    """The markdown tables: the summary (summary_table), then per set of videos one row per
    variant, each measure as present -> removed (the difference and its noise)."""
    lines = summary_table(out)
    names = [n for n in out["variants"] if n != "present"]
    if "renders" in out:
        r = out["renders"]["measures"]
        every = list(r["present"])
        for title, videos in (
                ("Validation renders", [v for v in every if "reversed" not in v]),
                ("The same renders time-reversed (backward walks)",
                 [v for v in every if "reversed" in v]),
                ("All renders, forward and time-reversed", every)):
            if videos and (title[0] != "A" or len(videos) > 12):
                lines += _render_table(title, r, names, videos)
    for trial, result in out.get("real", {}).items():
        lines += _real_table(trial, result["measures"], names)
    parts = ([("renders", out["renders"])] if "renders" in out else []) + list(
        out.get("real", {}).items())
    for part, result in parts:
        cpu = result["cpu_s"]
        lines.append(f"\nCPU seconds ({part}): capture (``track`` once per video) "
                     f"{cpu['capture']:.0f}; replays " + ", ".join(
                         f"{k} {v:.0f}" for k, v in cpu.items() if k != "capture"))
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
