"""Evaluate accuracy and jitter of per_frame, stacked, kalman and smoothed poses on a sequence.

    python scripts/evaluate_jitter.py --ankur ../shared/data/ankur/ankurDataPoseSilhouette.mat \
        --json ankur.json --report docs/evaluation/ankur
    python scripts/evaluate_jitter.py --bvh ../shared/data/cmu/bvh/16_11.bvh --spiral 30 \
        [--through-video] [--model FILE] --report docs/evaluation/16_11

Prints a table; --json writes the measures, --report DIR a markdown report with plots.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


from threadpoolctl import threadpool_limits

from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
from regressor.errors import SilhouettePoseError
from tracker import TrackerSettings
from tracker.offline.evaluation import (AnkurOptions, CameraOptions, ankur_sequence, evaluate,
                                        rendered_sequence, video_sequence)
from tracker.offline.report import format_table, write_report
from tracker.one_line_parser import OneLineParser

PER_FRAME_MODEL = DEFAULT_MODEL_PATH.with_name("per_frame_model.npz")


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like 320x240, got {text!r}")
    return h, w


def build_parser() -> argparse.ArgumentParser:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--ankur", type=Path, help="the paper's ankurDataPoseSilhouette.mat")
    src.add_argument("--bvh", type=Path, help="a CMU BVH file to render and evaluate")
    ap.add_argument("--spiral", type=float, metavar="DEG_PER_S", help="as a spiral walk")
    ap.add_argument("--through-video", action="store_true", help="write an mp4 and run track")
    ap.add_argument("--video", type=Path, help="keep the --through-video mp4 here")
    ap.add_argument("--model", type=Path, default=DEFAULT_MODEL_PATH, help="stacked model")
    ap.add_argument("--per-frame-model", type=Path, default=PER_FRAME_MODEL, help="k=1 model")
    ap.add_argument("--size", type=_size, default=(240, 320), help="WIDTHxHEIGHT (320x240)")
    ap.add_argument("--frames", type=int, help="evaluate only the first N frames")
    ap.add_argument("--ambiguity-threshold", type=float, help="default: the model's")
    ap.add_argument("--heading-factor", type=float,
                    default=TrackerSettings.ambiguous_heading_factor)
    ap.add_argument("--joint-factor", type=float, default=None,
                    help="joints' R inflation on ambiguous frames (default: the model's, "
                         "tracker.pipeline.TrackerSettings.joint_factor)")
    ap.add_argument("--r-scale", type=float, help="multiply the filter's R (default 1; --ankur: "
                    "chosen on the training split)")
    ap.add_argument("--q-scale", type=float, default=1.0, help="multiply the filter's q")
    ap.add_argument("--json", type=Path, metavar="OUT", help="write the measures as JSON")
    ap.add_argument("--report", type=Path, metavar="DIR", help="write a markdown report")
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
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
                extra = {"video": args.video} if args.through_video else {}
                seq = make(args.bvh, *models, args.spiral, CameraOptions(size=args.size),
                           settings, args.frames, **extra)
        result = evaluate(seq)
        print(format_table(result))
        if args.json:
            args.json.write_text(json.dumps(result, indent=1))
        if args.report:
            print(f"report: {write_report(args.report, seq, result)}")
    except (OSError, SilhouettePoseError, ValueError) as exc:
        print(f"evaluate_jitter: error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
