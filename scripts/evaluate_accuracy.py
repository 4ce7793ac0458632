"""Does the output follow the body? Models side by side on spiral-walk videos through `track`.

    python scripts/evaluate_accuracy.py --model shipped=regressor/models/default_model.npz \
        --model new=FILE [--trials 16_11 02_02 08_03] [--json out.json]

For each trial a 320x240 video is rendered as a 30 deg/s spiral walk (the shipped sample's
settings; 16_11 uses the shipped sample itself) into --video-dir (reused when present), run
through the tracker (background subtraction, stacking, Kalman filter) and compared with its
ground truth on the tracked frames. Measures (issue 9), for the raw per-frame regressor output
and the filtered output that `track` streams:

  err53   mean |wrapped error| of the 53 joint angles, degrees
  const   the same for a constant pose: the FIRST model's training-mean pose (its angle centres)
  skill   1 - err53 / const
  corr8   mean correlation with the truth of the 8 angles that move most in the truth
  flex    mean |error| of knee and elbow flexion (angle between the bones, forward kinematics
          on the CMU skeleton), degrees; flexC: the constant pose's; flexM: the truth's own mean
          flexion's (a constant that knows each sequence's average)
  head    heading RMS error, degrees
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from regressor.pose_model import load_pose_model  # noqa: E402
from sequences.body import sample_body_shapes  # noqa: E402
from sequences.pose_vector import joint_positions  # noqa: E402
from sequences.skeleton import POSE_JOINTS  # noqa: E402
from sequences.video import Actor, load_truth, write_video  # noqa: E402
from tracker.evaluation import CameraOptions, cmu_motion, track_video  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SAMPLE = REPO / "sequences" / "data" / "sample_spiral_walk.mp4"
FLEXION = {"left knee": ("LeftUpLeg", "LeftLeg", "LeftFoot"),
           "right knee": ("RightUpLeg", "RightLeg", "RightFoot"),
           "left elbow": ("LeftArm", "LeftForeArm", "LeftHand"),
           "right elbow": ("RightArm", "RightForeArm", "RightHand")}


def wrap(d):
    return (d + 180.0) % 360.0 - 180.0


def flexion(pose: np.ndarray) -> np.ndarray:
    """Knee and elbow flexion (T, 4) degrees: 180 - the angle at the joint between its bones."""
    P = joint_positions(pose)
    out = []
    for a, b, c in FLEXION.values():
        ia, ib, ic = (POSE_JOINTS.index(n) for n in (a, b, c))
        u, v = P[:, ib] - P[:, ia], P[:, ic] - P[:, ib]
        cos = (u * v).sum(-1) / (np.linalg.norm(u, axis=-1) * np.linalg.norm(v, axis=-1) + 1e-12)
        out.append(np.degrees(np.arccos(np.clip(cos, -1, 1))))
    return np.column_stack(out)


def measures(est: np.ndarray, truth: np.ndarray, constant_deg: np.ndarray) -> dict:
    """The module docstring's measures of poses est (T, 55) against truth (T, 55)."""
    e = wrap(est[:, 2:] - truth[:, 2:])
    c = wrap(constant_deg[None] - truth[:, 2:])
    err, const = float(np.abs(e).mean()), float(np.abs(c).mean())
    moving = np.argsort(-truth[:, 2:].std(axis=0))[:8]
    t = truth[:, 2:][:, moving]
    p = t + e[:, moving]
    corr = [np.corrcoef(p[:, j], t[:, j])[0, 1] if p[:, j].std() > 1e-9 else 0.0
            for j in range(8)]
    const_pose = np.concatenate([[1.0, 0.0], constant_deg])[None].repeat(len(truth), 0)
    ft, fe, fc = flexion(truth), flexion(est), flexion(const_pose)
    heading = wrap(np.degrees(np.arctan2(est[:, 1], est[:, 0]) - np.arctan2(truth[:, 1], truth[:, 0])))
    fcorr = [np.corrcoef(fe[:, j], ft[:, j])[0, 1] if fe[:, j].std() > 1e-9 else 0.0
             for j in range(4)]
    return {"err53": err, "const": const, "skill": 1 - err / const,
            "corr8": float(np.mean(corr)), "flex": float(np.abs(fe - ft).mean()),
            "flexC": float(np.abs(fc - ft).mean()),
            "flexM": float(np.abs(ft.mean(0) - ft).mean()),
            "flex_corr": float(np.mean(fcorr)),
            "head": float(np.sqrt((heading ** 2).mean()))}


def trial_video(trial: str, bvh_dir: Path, video_dir: Path) -> Path:
    """The spiral-walk video of a trial (the shipped sample for 16_11), rendered once."""
    if trial == "16_11":
        return SAMPLE
    path = video_dir / f"{trial}_spiral30.mp4"
    if not path.is_file():
        cam = CameraOptions()
        motion = cmu_motion(bvh_dir / f"{trial}.bvh", 30.0, cam.fps)
        write_video(path, [Actor(motion, shape=sample_body_shapes(1, seed=cam.seed)[0])],
                    size=cam.size, fps=cam.fps, azimuth_deg=cam.azimuth_deg,
                    elevation_deg=cam.elevation_deg, distance_m=cam.distance_m,
                    noise_sigma=cam.noise_sigma, seed=cam.seed)
    return path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", action="append", required=True, help="NAME=FILE (repeatable)")
    ap.add_argument("--trials", nargs="+", default=["16_11", "02_02", "08_03"])
    ap.add_argument("--bvh-dir", type=Path, default=REPO.parent / "shared/data/cmu/bvh")
    ap.add_argument("--video-dir", type=Path, default=Path("cache/videos"))
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    models = [(n, load_pose_model(p)) for n, p in (m.split("=", 1) for m in args.model)]
    constant = models[0][1].angle_centre_deg
    args.video_dir.mkdir(parents=True, exist_ok=True)
    results = []
    cols = ("err53", "const", "skill", "corr8", "flex", "flexC", "flexM", "flex_corr", "head")
    print(f"{'trial':7s} {'model':14s} {'output':8s} " + " ".join(f"{c:>9s}" for c in cols)
          + "      fps")
    with threadpool_limits(1):
        for trial in args.trials:
            video = trial_video(trial, args.bvh_dir, args.video_dir)
            truth_all = load_truth(video)["pose"][:, 0]
            for name, model in models:
                start = time.perf_counter()
                idx, raw, filtered = track_video(video, model, 0.5)[:3]
                fps = len(truth_all) / (time.perf_counter() - start)
                for output, est in (("raw", raw), ("filtered", filtered)):
                    m = measures(est, truth_all[idx], constant)
                    results.append({"trial": trial, "model": name, "output": output,
                                    "frames": int(len(idx)), "fps": fps, **m})
                    print(f"{trial:7s} {name:14s} {output:8s} "
                          + " ".join(f"{m[c]:9.3f}" for c in cols) + f" {fps:8.0f}", flush=True)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
