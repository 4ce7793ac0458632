"""A walk seen by a panning camera against its static-camera twin, through each silhouette source.

    python scripts/evaluate_panning.py \
        --background-video ../shared/data/pose2sim/balancing/videos/cam01.mp4 \
        [--bvh ../shared/data/cmu/bvh/16_11.bvh] [--frames 300] [--pan 4] \
        [--silhouettes background segment auto] [--out-dir out/panning] [--json OUT]

A CMU walk is rendered as a 30 deg/s spiral walk at 640x480 without sensor noise
(lab.evaluation.write_camera_video), its body cut out of the frames (where they differ
from the render's own textured scene, holes filled) and pasted over a real background: the top 15 %
of a video's first frame, above its subject (ceiling, lights, cameras), scaled 2x; 640x480 of it
seen through a window that stays put (the static twin) or pans left and right at --pan px per frame
(the panning video); sensor noise (2 grey levels) is added to both. The body itself does not move
with the pan: the background moves behind it, which is what a camera turning to follow its subject
shows. Each video is tracked (tracker.run.track_video, one process, at most one person) with each
silhouette source and its longest track's poses compared with the render's ground truth
(sequences.measures.pose_measures: err53, corr8, flexion, heading, MPJPE), filtered and smoothed,
with the share of frames tracked. Needs the segment extra for segment and auto.
"""
from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
from threadpoolctl import threadpool_limits

from regressor.pose_model import load_pose_model
from sequences.measures import pose_measures
from sequences.video import load_truth, textured_background, truth_path
from tracker.video.background import fill_holes
from lab.evaluation import CameraOptions, cmu_motion, constant_pose, write_camera_video
from tracker.one_line_parser import OneLineParser
from tracker.pipeline import PoseTracker, TrackerSettings
from tracker.run import track_video
from tracker.video.sources import (INSTALL_HINT, SOURCES, segmenter_available,
                                   silhouette_extractor)
from tracker.outputs import PoseRecorder

REPO = Path(__file__).resolve().parents[1]
SIZE = (480, 640)                     # (height, width)


def scene_image(video: Path) -> np.ndarray:
    """The top 15 % of the video's first frame (above its subject's head: ceiling, lights,
    cameras, a textured view), scaled 2x: BGR uint8."""
    capture = cv2.VideoCapture(str(video))
    ok, frame = capture.read()
    capture.release()
    if not ok:
        raise SystemExit(f"evaluate_panning: error: {video}: no frame decodes")
    top = frame[:int(0.15 * frame.shape[0])]
    return cv2.resize(top, (top.shape[1] * 2, top.shape[0] * 2), interpolation=cv2.INTER_CUBIC)


def body_mask(frame: np.ndarray, scene: np.ndarray) -> np.ndarray:
    """Where the noiseless render ``frame`` (BGR uint8) shows the body: it differs from the
    render's own scene (int16) by over 20 grey levels, closed (5 px) and with enclosed holes
    filled (where the shaded body matches the scene's colour). uint8 (H, W), 255 = body."""
    body = (np.abs(frame.astype(np.int16) - scene).max(axis=2) > 20).astype(np.uint8) * 255
    body = cv2.morphologyEx(body, cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    return fill_holes(cv2.morphologyEx(body, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8)))


def window_x(t: int, pan: float, span: int) -> int:
    """Left edge of the window at frame t: a triangle wave over 0..span at pan px per frame
    (the middle of the image when pan is 0)."""
    if pan == 0 or span <= 0:
        return span // 2
    position = (t * pan) % (2 * span)
    return int(position if position <= span else 2 * span - position)


def composite(render: Path, background: np.ndarray, pan: float, out: Path,
              noise: float = 2.0, seed: int = 1) -> None:
    """The noiseless render's body pasted over the background's moving window (module
    docstring), written to ``out`` with the render's ground truth beside it."""
    height, width = SIZE
    if background.shape[0] < height or background.shape[1] < width:
        background = cv2.resize(background, (max(width, background.shape[1]),
                                             max(height, background.shape[0])))
    scene = cv2.cvtColor(textured_background(SIZE, 0), cv2.COLOR_RGB2BGR).astype(np.int16)
    rng = np.random.default_rng(seed)
    y0 = (background.shape[0] - height) // 2
    span = background.shape[1] - width
    capture = cv2.VideoCapture(str(render))
    writer = cv2.VideoWriter(str(out), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (width, height))
    t = 0
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        body = body_mask(frame, scene)
        x0 = window_x(t, pan, span)
        image = background[y0:y0 + height, x0:x0 + width].astype(np.float32)
        image[body > 0] = frame[body > 0]
        image += rng.normal(0, noise, image.shape).astype(np.float32)
        writer.write(np.clip(image, 0, 255).astype(np.uint8))
        t += 1
    writer.release()
    capture.release()
    truth = dict(np.load(truth_path(render)))
    np.savez_compressed(truth_path(out), **truth)


def track_one(video: Path, model, source: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frame indices, filtered poses, smoothed poses) of the longest track of ``video``
    tracked with silhouette source ``source``."""
    settings = TrackerSettings(max_people=1, keep_history=True)
    recorder = PoseRecorder()
    from tracker.video.decode import open_video
    opened = open_video(video)
    tracker = PoseTracker(model, opened.fps, settings,
                          extractor=silhouette_extractor(source, settings))
    track_video(opened, tracker, [recorder], workers=1).stop_if_interrupted()
    by_track = recorder.by_track()
    if not by_track:
        return np.zeros(0, int), np.zeros((0, 55)), np.zeros((0, 55))
    track_id = max(by_track, key=lambda t: len(by_track[t]))
    poses = by_track[track_id]
    return (np.array([p.frame_index for p in poses]), np.array([p.filtered for p in poses]),
            tracker.smoothed_track(track_id))


def main(argv=None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--background-video", type=Path, required=True)
    ap.add_argument("--bvh", type=Path, default=REPO.parent / "shared/data/cmu/bvh/16_11.bvh")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--pan", type=float, default=4.0, help="px per frame (default 4)")
    ap.add_argument("--silhouettes", nargs="+", choices=SOURCES, default=list(SOURCES))
    ap.add_argument("--out-dir", type=Path, default=Path("out/panning"))
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    if {"segment", "auto"} & set(args.silhouettes) and not segmenter_available():
        ap.error(f"--silhouettes segment and auto need the person segmenter: {INSTALL_HINT}")
    if not args.background_video.is_file():
        ap.error(f"--background-video {args.background_video}: no such file")
    if not args.bvh.is_file():
        ap.error(f"--bvh {args.bvh}: no such file")
    args.out_dir.mkdir(parents=True, exist_ok=True)
    render = args.out_dir / "walk_noiseless.mp4"
    if not render.is_file():
        camera = replace(CameraOptions(), size=SIZE, noise_sigma=0.0)
        write_camera_video(render, cmu_motion(args.bvh, 30.0), camera, frames=args.frames)
    background = scene_image(args.background_video)
    videos = {"static": args.out_dir / "walk_static.mp4", "panning": args.out_dir / "walk_pan.mp4"}
    for name, video in videos.items():
        composite(render, background, 0.0 if name == "static" else args.pan, video)
    model = load_pose_model()
    constant = constant_pose(model)
    results = []
    print(f"{'video':8s} {'source':10s} {'output':8s} {'tracked':>7s} {'err53':>6s} "
          f"{'corr8':>6s} {'flex':>6s} {'head':>6s} {'mpjpe':>6s}")
    with threadpool_limits(1):
        for name, video in videos.items():
            truth = load_truth(video)["pose"][:, 0]
            for source in args.silhouettes:
                idx, filtered, smoothed = track_one(video, model, source)
                for output, est in (("filtered", filtered), ("smoothed", smoothed)):
                    row = {"video": name, "source": source, "output": output,
                           "tracked": len(idx) / len(truth)}
                    if len(idx) >= 3:
                        m = pose_measures(est, truth[idx], constant)
                        row.update(err53=m["error_deg"], corr8=m["top_angles"]["mean"],
                                   flex=m["flexion"]["error"], head=m["heading_rms_deg"],
                                   mpjpe=m["mpjpe_mm"])
                    results.append(row)
                    values = " ".join(f"{row.get(c, float('nan')):6.3f}" if c == "corr8" else
                                      f"{row.get(c, float('nan')):6.1f}"
                                      for c in ("err53", "corr8", "flex", "head", "mpjpe"))
                    print(f"{name:8s} {source:10s} {output:8s} {row['tracked']:7.1%} {values}",
                          flush=True)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
