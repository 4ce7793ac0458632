"""Draw the training body fitted to Pose2Sim's reference over the real video, to check the fit.

    python scripts/draw_fitted_body.py docs/evaluation/pose2sim/fitted_body.jpg
        [--trial ../shared/data/pose2sim/balancing] [--frames 10 50 90]

Fits the project's body to the reference keypoints of those frames (sequences.keypoint_fit,
~0.3 s a frame), renders
it through each calibrated camera (sequences.pose2sim.render_view_masks) and draws its outline
in red on the given video frames, one row per view, each tile cropped round the body. The
outline should follow the subject: it is the silhouette `evaluate_real.py --reference-masks
rendered` gives the regressor.
"""
from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

from sequences.body import load_body
from sequences.keypoint_fit import KeypointFitError, fit_body, posed_vertices
from sequences.pose2sim import (DEFAULT_TRIAL, VIEWS, Pose2SimError, load_trial,
                                render_view_masks, video_frames)
from tracker.one_line_parser import OneLineParser
from tracker.video import VideoError, open_video

_TILE_PX = 260          # tile height
_MARGIN_PX = 100        # around the body's box in the frame


def _tile(image: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The frame with the mask's outline drawn, cropped round it, _TILE_PX tall."""
    image = image.copy()
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL,
                                   cv2.CHAIN_APPROX_NONE)
    cv2.drawContours(image, contours, -1, (0, 0, 255), 4)
    rows, cols = np.nonzero(mask)
    y0, x0 = max(rows.min() - _MARGIN_PX, 0), max(cols.min() - _MARGIN_PX, 0)
    crop = image[y0:rows.max() + _MARGIN_PX, x0:cols.max() + _MARGIN_PX]
    scale = _TILE_PX / crop.shape[0]
    return cv2.resize(crop, (max(1, round(crop.shape[1] * scale)), _TILE_PX))


def draw(trial, frames: list[int]) -> np.ndarray:
    """One BGR image: a row per view, a tile per frame (video frame indices)."""
    available = set(video_frames(trial).tolist())
    missing = [f for f in frames if f not in available]
    if missing:
        raise Pose2SimError(f"frame {missing[0]} has no reference (the reference covers "
                            f"video frames {min(available)}..{max(available)})")
    body = load_body()
    fit = fit_body(trial.points(frames), trial.reference.names, body)
    vertices = posed_vertices(fit, body)
    lines = []
    for view in VIEWS:
        source = open_video(trial.video(view))
        masks = render_view_masks(vertices, body.faces, body.patch_start, trial.camera(view),
                                  (source.height, source.width))
        images = {}
        for index, _, image in source:          # decoded only as far as the last frame drawn
            if index in frames:
                images[index] = image
            if index >= max(frames):
                break
        lines.append(np.hstack([_tile(images[f], m) for f, m in zip(frames, masks)]))
    width = max(line.shape[1] for line in lines)
    return np.vstack([np.pad(line, ((0, 0), (0, width - line.shape[1]), (0, 0)))
                      for line in lines])


def main(argv=None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="image to write (.jpg or .png)")
    ap.add_argument("--trial", type=Path, default=DEFAULT_TRIAL, help="the balancing trial "
                    "folder (default: ../shared/data/pose2sim/balancing beside the repo)")
    ap.add_argument("--frames", type=int, nargs="+", default=[10, 50, 90],
                    help="video frames to draw (default: 10 50 90)")
    args = ap.parse_args(argv)
    if args.out.suffix.lower() not in (".jpg", ".jpeg", ".png"):
        print(f"draw_fitted_body: error: {args.out}: give a .jpg or .png name", file=sys.stderr)
        return 1
    try:
        image = draw(load_trial(args.trial), sorted(set(args.frames)))
        if not cv2.imwrite(str(args.out), image, [cv2.IMWRITE_JPEG_QUALITY, 80]):
            raise Pose2SimError(f"{args.out}: cannot write the image")
    except (Pose2SimError, KeypointFitError, VideoError, cv2.error) as exc:
        print(f"draw_fitted_body: error: {exc}", file=sys.stderr)
        return 1
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
