"""Does the output follow the body? Models side by side on spiral-walk videos through `track`.

    python scripts/evaluate_accuracy.py --model shipped=regressor/models/default_model.npz \
        --model new=FILE [--trials 16_11 02_02 08_03] [--json out.json]

For each trial a 320x240 video is rendered as a 30 deg/s spiral walk (the shipped sample's
settings; 16_11 uses the shipped sample itself; --fps renders them at another frame rate, the
sample too) into --video-dir (reused when present), run
through the tracker (background subtraction, stacking, Kalman filter) and compared with its
ground truth on the tracked frames. Measures (issue 9), for the raw per-frame regressor output,
the filtered output that `track` streams, what it streams with `--lag S` (row lagS; --lag,
default 0.5) and the smoothed output of `track --smooth`:

  err53   mean |wrapped error| of the 53 joint angles, degrees
  const   the same for a constant pose: the FIRST model's training-mean pose (its angle centres)
  skill   1 - err53 / const
  off53   err53 with each angle's constant offset over the sequence forgiven (how well the
          output follows the motion, whatever a subject's own offsets); offC: the constant
          pose's (the truth's own mean absolute deviation: a still output scores that, not 0)
  corr8   mean correlation with the truth of the 8 angles that move most in the truth
  flex    mean |error| of knee and elbow flexion (angle between the bones, forward kinematics
          on the CMU skeleton), degrees; flexC: the constant pose's; flexM: the truth's own mean
          flexion's (a constant that knows each sequence's average)
  head    heading RMS error, degrees
  mpjpe   mean per-joint position error, millimetres (root-aligned)

and, per trial and model, the inputs' novelty (PoseEstimates.novelty: distance to the training
silhouettes over their own 99th percentile; fps includes its extra query per frame).

A --video-dir that is a file, or a --json that could not be written or would overwrite what
the run reads or renders (a model; a trial's BVH, video or ground truth, the shipped sample's
too; a file named like them in --bvh-dir or --video-dir) is refused before any work (exit 2).
Bad input (a malformed BVH, a broken video or ground-truth file, a video with nobody in it)
ends the run with one line naming the trial and the file, exit 1; Ctrl-C with one line, exit
130. A video is rendered under a temporary name and renamed, with its ground truth, once
complete: an interrupted run leaves no half-written video for the next one to choke on.
"""
from __future__ import annotations

import json
import os
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from regressor.errors import SilhouettePoseError
from regressor.pose_model import load_pose_model
from sequences.measures import novelty_summary, pose_measures
from sequences.pose_vector import POSE_DIM
from sequences.video import load_truth, replace_video, truth_path
from tracker.cli import VIEW_LAG_S
from tracker.tracks.fixed_lag import MAX_LAG_S
from lab.evaluation import (CameraOptions, cmu_motion, constant_pose, track_longest,
                                        write_camera_video)
from tracker.one_line_parser import OneLineParser, quiet_decoder_logs, stops_in_one_line
from tracker.pipeline import TrackerSettings
from tracker.outputs.files import OutputWriteError
from tracker.outputs.whole_files import write_whole

REPO = Path(__file__).resolve().parents[1]
SAMPLE = REPO / "sequences" / "data" / "sample_spiral_walk.mp4"
#: What reading a trial's files or tracking its video raises on bad data: the project's own
#: errors, and what numpy and the standard library raise on a file that is not what it says.
BAD_DATA = (SilhouettePoseError, ValueError, UnicodeDecodeError, MemoryError, OSError,
            zipfile.BadZipFile, EOFError, KeyError)


def measures(est, truth, constant) -> dict:
    """The module docstring's measures of poses est (T, 55) against truth (T, 55), beside a
    constant pose (55,) (sequences.measures.pose_measures, flattened for the table)."""
    m = pose_measures(est, truth, constant)
    return {"err53": m["error_deg"], "const": m["constant_error_deg"], "skill": m["skill"],
            "off53": m["offset_free_error_deg"], "offC": m["constant_offset_free_error_deg"],
            "corr8": m["top_angles"]["mean"], "flex": m["flexion"]["error"],
            "flexC": m["flexion"]["constant_error_mean"],
            "flexM": m["flexion"]["truth_mean_error_mean"], "flex_corr": m["flexion"]["corr"],
            "head": m["heading_rms_deg"], "mpjpe": m["mpjpe_mm"]}


def video_path(trial: str, video_dir: Path, fps: float = 30.0) -> Path:
    """Where a trial's spiral-walk video is (the shipped sample for 16_11 at 30 fps)."""
    if fps == 30.0:
        return SAMPLE if trial == "16_11" else video_dir / f"{trial}_spiral30.mp4"
    return video_dir / f"{trial}_spiral30_{fps:g}fps.mp4"


def trial_motion(trial: str, bvh_dir: Path, fps: float = 30.0):
    """The trial's motion capture as the spiral walk its video shows, at fps."""
    return cmu_motion(bvh_dir / f"{trial}.bvh", 30.0, fps)


def trial_video(trial: str, bvh_dir: Path, video_dir: Path, fps: float = 30.0,
                motion=None) -> Path:
    """The spiral-walk video of a trial at fps frames per second (the shipped sample for
    16_11 at 30), rendered once (from motion, default trial_motion's)."""
    path = video_path(trial, video_dir, fps)
    if not path.is_file():
        cam = CameraOptions(fps=fps)
        motion = trial_motion(trial, bvh_dir, fps) if motion is None else motion
        replace_video(path, lambda partial: write_camera_video(partial, motion, cam))
    return path


def truth_problem(video: Path) -> str | None:
    """Why the ground truth beside an existing video cannot be used (missing, unreadable, no
    poses), naming the files to delete so that the next run renders them again; or None."""
    sidecar = truth_path(video)
    if not sidecar.is_file():
        return (f"{video} has no ground truth {sidecar} (an interrupted render?); delete "
                f"{video} to render it again")
    try:
        pose = load_truth(video)["pose"]
        if pose.ndim != 3 or not (len(pose) and pose.shape[1]) or pose.shape[2] != POSE_DIM:
            raise ValueError(f"poses of shape {pose.shape}, expected (frames, people, "
                             f"{POSE_DIM})")
    except BAD_DATA as exc:
        return (f"{sidecar}: unusable ground truth ({str(exc).splitlines()[0]}); delete "
                f"{video} and {sidecar} to render them again")
    return None


def _named_models(ap, specs: list[str]) -> list[tuple[str, Path, object]]:
    """(name, file, model) for each --model NAME=FILE; one-line errors (ap.error) for a
    malformed option, a repeated name or a file that does not load."""
    models = []
    for spec in specs:
        name, sep, path = spec.partition("=")
        if not sep or not name or not path:
            ap.error(f"--model takes NAME=FILE, got {spec!r}")
        if name in (n for n, _, _ in models):
            ap.error(f"--model name {name!r} given twice")
        try:
            models.append((name, Path(path), load_pose_model(path)))
        except (OSError, SilhouettePoseError) as exc:
            ap.error(f"--model {name}: {exc}")
    return models


def _main(argv) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", action="append", required=True, help="NAME=FILE (repeatable)")
    ap.add_argument("--trials", nargs="+", default=["16_11", "02_02", "08_03"])
    ap.add_argument("--bvh-dir", type=Path, default=REPO.parent / "shared/data/cmu/bvh")
    ap.add_argument("--video-dir", type=Path, default=Path("cache/videos"))
    ap.add_argument("--json", type=Path)
    ap.add_argument("--fps", type=float, default=30.0,
                    help="render the videos at this frame rate (default 30, the sample's; "
                    "others are rendered as TRIAL_spiral30_FPSfps.mp4)")
    ap.add_argument("--lag", type=float, default=VIEW_LAG_S, metavar="S",
                    help="also measure the poses `track --lag S` streams (default "
                    f"{VIEW_LAG_S:g}, --view's default)")
    args = ap.parse_args(argv)
    if not (np.isfinite(args.lag) and 0 < args.lag <= MAX_LAG_S):
        ap.error(f"--lag must be above 0 and at most {MAX_LAG_S:g} seconds, got {args.lag}")
    if not (np.isfinite(args.fps) and 10.0 <= args.fps <= 240.0):
        ap.error(f"--fps must be between 10 and 240 frames per second, got {args.fps}")
    named = _named_models(ap, args.model)
    if args.video_dir.exists() and not args.video_dir.is_dir():
        ap.error(f"--video-dir {args.video_dir} is a file, not a folder")
    for trial in args.trials:           # before any tracking, not after some trials
        video = video_path(trial, args.video_dir, args.fps)
        if not video.is_file() and not (args.bvh_dir / f"{trial}.bvh").is_file():
            ap.error(f"trial {trial}: neither {video} nor {args.bvh_dir / f'{trial}.bvh'} "
                     f"exists")
    if args.json is not None and not args.json.parent.is_dir():
        ap.error(f"--json {args.json}: no folder {args.json.parent}")
    if args.json is not None and any(args.json.resolve() == path.resolve()
                                     for _, path, _ in named):
        ap.error(f"--json {args.json} is a model file: it would be overwritten")
    _check_json(ap, args, named)
    quiet_decoder_logs()          # as track: one line, not FFmpeg's too
    return _evaluate(args, [(name, model) for name, _, model in named])


def _check_json(ap, args, named) -> None:
    """Refuse a --json that could not be written or would overwrite what the run reads or
    renders: a model, a trial's BVH, video or ground truth (the shipped sample's too), or a
    file named like them in --bvh-dir or --video-dir (ap.error, one line)."""
    if args.json is None:
        return
    inputs = [(f"--model {name}", path) for name, path, _ in named]
    inputs += [("the shipped sample video", SAMPLE),
               ("the shipped sample's ground truth", truth_path(SAMPLE))]
    for trial in args.trials:
        video = video_path(trial, args.video_dir, args.fps)
        inputs += [(f"trial {trial}'s motion capture", args.bvh_dir / f"{trial}.bvh"),
                   (f"trial {trial}'s video", video),
                   (f"trial {trial}'s ground truth", truth_path(video))]
    folder = args.json.resolve().parent
    name = args.json.name.lower()
    for option, where, suffixes in (("--bvh-dir", args.bvh_dir, (".bvh",)),
                                    ("--video-dir", args.video_dir, (".mp4", ".npz"))):
        if folder == where.resolve() and name.endswith(suffixes):
            ap.error(f"--json {args.json} is named like the {option} files this script reads "
                     f"or writes; choose another file name")
    ap.check_outputs([("--json", args.json)], inputs)


def _evaluate(args, models: list[tuple[str, object]]) -> int:
    """The evaluation of the parsed, checked options: the table on stdout, --json; 1 with one
    line on stderr naming the trial and its file for bad data."""
    constant = constant_pose(models[0][1])
    motions = {}
    for trial in args.trials:           # bad data before any rendering or tracking
        video = video_path(trial, args.video_dir, args.fps)
        if video.is_file():
            problem = truth_problem(video)
            if problem:
                return _failed(f"trial {trial}: {problem}")
            continue
        bvh = args.bvh_dir / f"{trial}.bvh"
        try:
            motions[trial] = trial_motion(trial, args.bvh_dir, args.fps)
        except BAD_DATA as exc:
            return _failed(f"trial {trial}: {_about(bvh, exc)}")
    try:
        args.video_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return _failed(f"--video-dir {args.video_dir}: cannot create it ({exc.strerror})")
    if motions and not os.access(args.video_dir, os.W_OK):
        return _failed(f"--video-dir {args.video_dir}: not writable, and the videos of "
                       f"{', '.join(motions)} are to be rendered there")
    results = []
    cols = ("err53", "const", "skill", "off53", "offC", "corr8", "flex", "flexC", "flexM",
            "flex_corr", "head", "mpjpe")
    print(f"{'trial':7s} {'model':14s} {'output':8s} " + " ".join(f"{c:>9s}" for c in cols)
          + "      fps")
    with threadpool_limits(1):
        for trial in args.trials:
            video = video_path(trial, args.video_dir, args.fps)
            try:
                trial_video(trial, args.bvh_dir, args.video_dir, args.fps, motions.get(trial))
                truth_all = load_truth(video)["pose"][:, 0]
            except BAD_DATA as exc:
                return _failed(f"trial {trial}: {_about(video, exc)}")
            for name, model in models:
                start = time.perf_counter()
                try:
                    tracked = track_longest(video, model, TrackerSettings(novelty=True),
                                            args.lag)
                # The video's own problems (unreadable, nobody in it), not a bug's KeyError.
                except (SilhouettePoseError, OSError, MemoryError) as exc:
                    return _failed(f"trial {trial}, model {name}: {_about(video, exc)}")
                idx, raw, filtered, smoothed, novelty, lagged = *tracked[:4], *tracked[7:]
                fps = len(truth_all) / (time.perf_counter() - start)
                novel = novelty_summary(novelty)
                for output, est in (("raw", raw), ("filtered", filtered),
                                    (f"lag{args.lag:g}", lagged), ("smoothed", smoothed)):
                    m = measures(est, truth_all[idx], constant)
                    results.append({"trial": trial, "model": name, "output": output,
                                    "frames": int(len(idx)), "fps": fps, **m,
                                    "novelty": novel})
                    print(f"{trial:7s} {name:14s} {output:8s} "
                          + " ".join(f"{m[c]:9.3f}" for c in cols) + f" {fps:8.0f}", flush=True)
                if novel["median"] is not None:
                    print(f"{trial:7s} {name:14s} novelty: median {novel['median']:.2f}, max "
                          f"{np.nanmax(novelty):.2f}, above 1 in "
                          f"{100 * novel['share_above_1']:.1f} % of frames", flush=True)
    if args.json:
        try:             # whole or not at all: a re-run's --json keeps the last complete one
            write_whole(args.json, lambda path: path.write_text(json.dumps(results, indent=1)))
        except OutputWriteError as exc:
            return _failed(str(exc))
    return 0


def _about(path: Path, exc: BaseException) -> str:
    """An exception about a file as one line that names the file by its path: its first line
    (its type's name if it has none: MemoryError), after the path unless it names the file
    (a BVHError starts with the file's name alone: given its path)."""
    text = str(exc).strip()
    line = text.splitlines()[0] if text else type(exc).__name__
    if str(path) in line:
        return line
    if line.startswith((f"{path.name} ", f"{path.name}:")):
        return f"{path}{line[len(path.name):]}"
    return f"{path}: {line}"


def _failed(message: str) -> int:
    """One line on stderr; the exit status of bad data."""
    print(f"evaluate_accuracy: error: {message}", file=sys.stderr)
    return 1


main = stops_in_one_line("evaluate_accuracy", _main)       # Ctrl-C: one line, no traceback


if __name__ == "__main__":
    sys.exit(main())
