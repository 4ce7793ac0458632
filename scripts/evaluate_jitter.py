"""Evaluate accuracy and jitter of per_frame, stacked, kalman and smoothed poses on a sequence.

    python scripts/evaluate_jitter.py --ankur ../shared/data/ankur/ankurDataPoseSilhouette.mat \
        --json ankur.json --report docs/evaluation/ankur
    python scripts/evaluate_jitter.py --bvh ../shared/data/cmu/bvh/16_11.bvh --spiral 30 \
        [--through-video] [--model FILE] --report docs/evaluation/16_11

Prints a table; --json writes the measures, --report DIR a markdown report with plots.

--ankur trains the paper's regressor on its training split and takes --frames, --r-scale (the
filter's R; chosen on the training split when not given), --q-scale, --json and --report; the
other options render and track a --bvh motion with our models, and are refused with --ankur.
A --ankur file that is not the paper's data, or a --bvh too short for its --spiral, ends the
run in one line naming the file (exit 1).
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import shutil
import sys
import tempfile
from pathlib import Path


from threadpoolctl import threadpool_limits

from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
from regressor.errors import SilhouettePoseError
from sequences.body import BodyPoseError
from sequences.video import VIDEO_SUFFIXES, partial_video, replace_video, truth_path
from tracker import TrackerSettings
from lab.evaluation import (AnkurOptions, CameraOptions, ankur_sequence, evaluate,
                                        rendered_sequence, video_sequence)
from lab.report import format_table, write_report
from tracker.one_line_parser import EXIT_INTERRUPTED, OneLineParser
from tracker.outputs.whole_files import write_whole

PER_FRAME_MODEL = DEFAULT_MODEL_PATH.with_name("per_frame_model.npz")
#: What lab.report.write_report puts in the --report folder.
REPORT_FILES = ("README.md", "result.json", "parts.png", "jitter.png", "heading.png")
MIN_FRAMES = 3              # the jitter and acceleration measures take second differences
MAX_FRAMES = 1_000_000
DEFAULT_SIZE = (240, 320)   # (height, width)
#: Options (dest, flag) of the rendered --bvh motion alone: the paper's data has no video,
#: camera or models of ours, and its regressor and filter are fitted on its training split.
BVH_ONLY = (("spiral", "--spiral"), ("model", "--model"),
            ("per_frame_model", "--per-frame-model"), ("size", "--size"),
            ("ambiguity_threshold", "--ambiguity-threshold"),
            ("heading_factor", "--heading-factor"), ("joint_factor", "--joint-factor"))


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like 320x240, got {text!r}")
    return h, w


def build_parser() -> argparse.ArgumentParser:
    ap = OneLineParser(description=__doc__.splitlines()[0],
                       epilog="--ankur takes --frames, --r-scale, --q-scale, --json and "
                              "--report; the options marked (--bvh) are refused with it.")
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--ankur", type=Path, help="the paper's ankurDataPoseSilhouette.mat")
    src.add_argument("--bvh", type=Path, help="a CMU BVH file to render and evaluate")
    ap.add_argument("--spiral", type=float, metavar="DEG_PER_S", help="as a spiral walk (--bvh)")
    ap.add_argument("--through-video", action="store_true",
                    help="write an mp4 and run track (--bvh)")
    ap.add_argument("--video", type=Path, help="keep the --through-video mp4 here (--bvh)")
    # Defaults None, filled in by main: so that --ankur can tell them given.
    ap.add_argument("--model", type=Path, help=f"stacked model (--bvh; default "
                    f"{DEFAULT_MODEL_PATH.name})")
    ap.add_argument("--per-frame-model", type=Path,
                    help=f"k=1 model (--bvh; default {PER_FRAME_MODEL.name})")
    ap.add_argument("--size", type=_size, help="WIDTHxHEIGHT, 64..4096 each side (--bvh; "
                    f"default {DEFAULT_SIZE[1]}x{DEFAULT_SIZE[0]})")
    ap.add_argument("--frames", type=int, help=f"evaluate only the first N frames (N >= "
                    f"{MIN_FRAMES})")
    ap.add_argument("--ambiguity-threshold", type=float,
                    help="raw heading norm below which a frame is ambiguous, 0..1.5 (--bvh; "
                         "default: the model's)")
    ap.add_argument("--heading-factor", type=float,
                    help="heading's R inflation on ambiguous frames, >= 1 (--bvh; default "
                         f"{TrackerSettings.ambiguous_heading_factor:g})")
    ap.add_argument("--joint-factor", type=float, default=None,
                    help="joints' R inflation on ambiguous frames (--bvh; default: the "
                         "model's, tracker.pipeline.TrackerSettings.joint_factor)")
    ap.add_argument("--r-scale", type=float, help="multiply the filter's R (default 1; --ankur: "
                    "chosen on the training split)")
    ap.add_argument("--q-scale", type=float, default=1.0, help="multiply the filter's q")
    ap.add_argument("--json", type=Path, metavar="OUT", help="write the measures as JSON")
    ap.add_argument("--report", type=Path, metavar="DIR", help="write a markdown report")
    return ap


def _check_numbers(ap: OneLineParser, args) -> None:
    """Refuse absurd numbers in one line before the slow work: each finite and within what
    the filter (scales > 0, inflation factors >= 1, a (cos, sin) norm of 0..1.5 as threshold),
    the camera and the measures take."""
    bounds = [("--heading-factor", args.heading_factor, 1, 1e6),
              ("--joint-factor", args.joint_factor, 1, 1e6),
              ("--r-scale", args.r_scale, 1e-6, 1e6), ("--q-scale", args.q_scale, 1e-6, 1e6),
              ("--ambiguity-threshold", args.ambiguity_threshold, 0, 1.5),
              ("--spiral", args.spiral, -720, 720)]
    for flag, value, low, high in bounds:
        if value is not None and not (math.isfinite(value) and low <= value <= high):
            ap.error(f"{flag} must be within {low:g}..{high:g}, got {value}")
    if args.frames is not None and not MIN_FRAMES <= args.frames <= MAX_FRAMES:
        ap.error(f"--frames must be within {MIN_FRAMES}..{MAX_FRAMES} (the jitter measures "
                 f"need {MIN_FRAMES} frames), got {args.frames}")
    if args.size is not None and not all(64 <= side <= 4096 for side in args.size):
        ap.error(f"--size must be within 64..4096 pixels each side, got "
                 f"{args.size[1]}x{args.size[0]}")


def _check_files(ap: OneLineParser, args) -> None:
    """Refuse, before the slow work, missing inputs and outputs that could not be written or
    would overwrite an input or each other: --json, --video and its sidecar (and their
    temporary names), and the files --report writes into an existing folder."""
    if args.video is not None and not args.through_video:
        ap.error("--video keeps the --through-video mp4: give --through-video too")
    if args.through_video and args.ankur:
        ap.error("--through-video renders a --bvh motion; the paper's data has no video")
    given = [flag for dest, flag in BVH_ONLY if getattr(args, dest) is not None]
    if args.ankur and given:
        ap.error(f"{given[0]} is for a rendered --bvh motion; --ankur evaluates the paper's "
                 f"data with its own regressor (it takes --frames, --r-scale, --q-scale)")
    if args.bvh:                # the defaults, left None by the parser for the check above
        args.model = args.model or DEFAULT_MODEL_PATH
        args.per_frame_model = args.per_frame_model or PER_FRAME_MODEL
        args.size = args.size or DEFAULT_SIZE
        if args.heading_factor is None:
            args.heading_factor = TrackerSettings.ambiguous_heading_factor
    inputs = [("--ankur", args.ankur)] if args.ankur else [("--bvh", args.bvh)]
    if args.bvh:
        inputs += [("--model", args.model), ("--per-frame-model", args.per_frame_model)]
    for what, path in inputs:   # (the same model as both is no clash: check_outputs)
        if not path.is_file():
            ap.error(f"{what} {path}: no such file")
    outputs = [("--json", args.json)]
    if args.video is not None:
        if args.video.suffix.lower() not in VIDEO_SUFFIXES and not args.video.is_dir():
            ap.error(f"--video {args.video}: give a video name ending in "
                     f"{', '.join(VIDEO_SUFFIXES)}")
        partial = partial_video(args.video)
        outputs += [("--video", args.video), ("its ground-truth sidecar", truth_path(args.video)),
                    ("the temporary video", partial),
                    ("the temporary sidecar", truth_path(partial))]
    if args.report is not None:
        if args.report.exists() and not args.report.is_dir():
            ap.error(f"--report {args.report} is a file; give a folder")
        if args.report.is_dir():
            outputs += [(f"--report's {name}", args.report / name) for name in REPORT_FILES]
        else:               # made with its missing parents, as before: the nearest that
            parent = args.report.parent     # exists must take it
            while not parent.exists() and parent != parent.parent:
                parent = parent.parent
            if not (parent.is_dir() and os.access(parent, os.W_OK)):
                ap.error(f"--report {args.report}: cannot make it in {parent}")
        if importlib.util.find_spec("matplotlib") is None:
            ap.error("--report draws plots with matplotlib: pip install "
                     "'silhouette-pose[report]'")
    ap.check_outputs(outputs, inputs)
    for what, path in outputs[1:]:
        if path.exists() and not path.is_file():
            ap.error(f"{what} {path} exists and is not a regular file; choose another name")


def _write_report(folder: Path, seq, result: dict) -> Path:
    """write_report into a temporary folder beside ``folder``, then move its files into
    ``folder`` (created if need be) together: a failed or interrupted report leaves the old
    one as it was. Other files of ``folder`` are kept. Returns the README's path."""
    # Inside the folder itself (its parent may not be writable), so the renames stay on one
    # file system.
    folder.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix=".report.", suffix=".partial", dir=folder))
    try:
        write_report(scratch, seq, result)
        for made in sorted(scratch.iterdir()):
            os.replace(made, folder / made.name)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return folder / "README.md"


def main(argv=None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    _check_numbers(ap, args)
    _check_files(ap, args)
    written = []
    try:
        with threadpool_limits(1):      # small matrices: BLAS threads cost more than they save
            if args.ankur:
                seq = ankur_sequence(args.ankur, AnkurOptions(r_scale=args.r_scale,
                                                              q_scale=args.q_scale), args.frames)
            else:
                settings = TrackerSettings(ambiguity_threshold=args.ambiguity_threshold,
                                           ambiguous_heading_factor=args.heading_factor,
                                           ambiguous_joint_factor=args.joint_factor,
                                           r_scale=args.r_scale or 1.0, q_scale=args.q_scale)
                models = load_pose_model(args.model), load_pose_model(args.per_frame_model)
                make = video_sequence if args.through_video else rendered_sequence

                def sequence(**video):
                    return make(args.bvh, *models, args.spiral, CameraOptions(size=args.size),
                                settings, args.frames, **video)
                if args.video is None:
                    seq = sequence()
                else:
                    # The kept video is written and tracked under a temporary name, renamed
                    # once tracked: a failed or interrupted run leaves an older one intact.
                    made = []
                    replace_video(args.video, lambda partial: made.append(
                        sequence(video=partial)))
                    seq = made[0]
                    written.append(str(args.video))
        result = evaluate(seq)
        print(format_table(result))
        if args.json:
            write_whole(args.json, lambda path: path.write_text(json.dumps(result, indent=1)))
            written.append(str(args.json))
        if args.report:
            print(f"report: {_write_report(args.report, seq, result)}")
    except KeyboardInterrupt:
        done = f"wrote only {', '.join(written)}" if written else "nothing written"
        print(f"evaluate_jitter: interrupted; {done}", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BodyPoseError as exc:            # the file's skeleton, which the message does not name
        print(f"evaluate_jitter: error: --bvh {args.bvh}: {exc}", file=sys.stderr)
        return 1
    except (OSError, SilhouettePoseError, ValueError, MemoryError) as exc:
        print(f"evaluate_jitter: error: {' '.join(str(exc).split()) or type(exc).__name__}",
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
