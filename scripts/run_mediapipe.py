"""Run MediaPipe Pose on the Pose2Sim trials' views and save its landmarks for evaluate_real.

    python scripts/run_mediapipe.py [--trial all|balancing|swings|FOLDER] --out DIR

Writes DIR/TRIAL/camNN.npz per view (sequences.mediapipe_peer: world and pixel landmarks per
video frame, NaN where MediaPipe followed nobody), which ``evaluate_real.py --peer mediapipe
--peer-results DIR`` scores. Needs mediapipe 0.10.14 (pip install -e '.[peers]'); run it in its
own environment if mediapipe's requirements do not fit the main one (see docs/real_video.md).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from tracker.one_line_parser import OneLineParser
from sequences.mediapipe_peer import PeerError, keypoint_boxes, run_view, write_results
from sequences.pose2sim import (VIEWS, Pose2SimError, load_trial, project_reference, trial_roots,
                                video_frames)


def run_trial(root: Path, out: Path) -> None:
    """MediaPipe on every view of the trial at root, written to out/camNN.npz."""
    trial = load_trial(root)
    frames = video_frames(trial)
    if not np.array_equal(frames, np.arange(len(frames))):
        raise Pose2SimError(f"{root}: the reference must cover video frames 0..N-1")
    out.mkdir(parents=True, exist_ok=True)
    for view in VIEWS:
        boxes = keypoint_boxes(project_reference(view, frames, trial))
        results = run_view(trial.video(view), boxes)
        found = np.isfinite(results["world"][:, 0, 0]).sum()
        write_results(out / f"{view}.npz", results)
        print(f"{root.name} {view}: MediaPipe followed someone in {found}/{len(frames)} frames",
              flush=True)


def main(argv=None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trial", default="all", help="all (default), balancing, swings, or a "
                    "trial folder")
    ap.add_argument("--out", type=Path, required=True, help="folder for TRIAL/camNN.npz")
    args = ap.parse_args(argv)
    try:
        for name, root in trial_roots(args.trial).items():
            run_trial(root, args.out / name)
    except (Pose2SimError, PeerError, OSError) as exc:
        print(f"run_mediapipe: error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
